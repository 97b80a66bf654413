"""A client node in its own rclpy context and ROS domain: the base of every node that drives
or watches a run from outside (the test probe, the bench and soak observers).

It waits on conditions while spinning, calls ``std_srvs/Trigger`` services and sets and reads
parameters through the standard parameter services (what ``ros2 param`` uses).
Subclasses decide what one turn of spinning serves (:meth:`RosClient.spin_once`).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import ShutdownException, SingleThreadedExecutor, TimeoutException
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future
from std_srvs.srv import Trigger

#: Longest wait [s] of one turn of the default :meth:`RosClient.spin_once`.
SPIN_WAIT = 0.05
#: How often [s] :meth:`RosClient.spin_until` looks at its condition while another thread
#: spins (:meth:`RosClient.spinning_in_background`).
BACKGROUND_POLL = 0.002
#: Fast DDS reads its default XML profiles from the file this names, once per process.
PROFILES_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
#: The client participant's Fast DDS profiles: quicker discovery announcements and
#: heartbeats (the file says why and what they save).
CLIENT_PROFILES = Path(__file__).with_name("fastdds_client.xml")
#: How long [s] a request waits for its answer before it is sent again (up to the call's
#: timeout). A service answers a client only once it has matched the client's reply reader:
#: rmw_fastrtps waits 100 ms for that, then drops the answer and logs "failed to send
#: response (timeout)". On two loaded cores a new client's reader was sometimes not matched
#: in time, and its call waited out its 10 s (make test: a set_parameters, a ``~/pause``).
#: Sent again, the request finds the reader matched. Only for services whose second call
#: does what the first did (parameters, the plant's pause, resume, reset and release).
RESEND_AFTER = 2.0
#: Longest wait [s] for nodes just started to appear in the graph and connect (a probe's
#: ``wait_for_graph`` and ``wait_for_subscriber``, a recorder's matches, a latched config).
#: A lockstep run's three nodes (iiwa, inverse dynamics, recorder) connect 3 s after they
#: are started on an idle machine here; in CI's make test-long, four runs starting at once
#: beside another test on two cores, a controller was not subscribed after 20 s. The wait
#: ends as soon as they are connected, and at once if one of them exits (``check``).
STARTUP_TIMEOUT = 60.0


_profiles_lock = threading.Lock()


@contextmanager
def _client_profiles() -> Iterator[None]:
    """Within: a participant this process creates takes :data:`CLIENT_PROFILES`, where the
    user has named no Fast DDS profiles of their own (Fast DDS loads them once, with the
    process's first participant; the later ones take them too). The variable is removed
    again on leaving, so the node processes a client starts keep Fast DDS's defaults
    (other RMWs ignore it). One thread at a time: a sweep's runs start clients in threads."""
    with _profiles_lock:
        if PROFILES_ENV in os.environ:
            yield
            return
        os.environ[PROFILES_ENV] = str(CLIENT_PROFILES)
        try:
            yield
        finally:
            os.environ.pop(PROFILES_ENV, None)


class RosClient:
    """Owns its rclpy context in ``domain_id`` (localhost discovery unless the environment
    says otherwise); :meth:`close` when done."""

    def __init__(self, domain_id: int, name: str) -> None:
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        self.context = rclpy.Context()
        with _client_profiles():  # the participant is created with the first node
            rclpy.init(context=self.context, domain_id=domain_id)
            self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._param_clients: dict[str, AsyncParameterClient] = {}
        self._spinner: threading.Thread | None = None  # see spinning_in_background()
        self._spinner_errors: list[BaseException] = []

    # -- spinning ----------------------------------------------------------------------
    def spin_once(self) -> None:
        """One turn: executor work, waiting at most :data:`SPIN_WAIT`."""
        self.executor.spin_once(timeout_sec=SPIN_WAIT)

    def serve_ready(self, limit: int = 1000) -> None:
        """Everything the executor has ready (services, parameter clients, subscriptions on
        ``self.node``), without waiting; exceptions of the callbacks propagate. While
        :meth:`spinning_in_background`, only the spinning thread serves."""
        if self._spinner is not None and threading.current_thread() is not self._spinner:
            return
        for _ in range(limit):
            try:
                handler, _, _ = self.executor.wait_for_ready_callbacks(0)
            except (TimeoutException, ShutdownException):
                return
            handler()
            if handler.exception() is not None:
                raise handler.exception()

    def spin_until(
        self,
        done: Callable[[], bool],
        timeout: float,
        what: str,
        check: Callable[[], None] | None = None,
    ) -> None:
        """Spin until ``done()``; ``check()`` (e.g. "are the node processes alive") each
        turn; TimeoutError naming ``what`` after ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while not done():
            if time.monotonic() > end:
                raise TimeoutError(f"timed out after {timeout:g} s waiting for {what}")
            if check is not None:
                check()
            if self._spinner is None:
                self.spin_once()
            elif self._spinner_errors:
                raise self._spinner_errors[0]
            else:
                time.sleep(BACKGROUND_POLL)  # the spinning thread serves

    @contextmanager
    def spinning_in_background(self) -> Iterator[None]:
        """Spin in a thread of its own while the block runs, for a caller busy elsewhere
        for seconds at a time (a test driving a browser). A reliable reader left that long
        behind a 1 kHz writer was found stalled for good against it: the page test's probe
        took no joint state, no controller status and no parameter answer for 30 s after
        typing a set-point (docs/dashboard.md). Within the block :meth:`spin_until` waits
        while the thread spins; a callback's exception is raised in the caller, there or at
        the end of the block."""
        stop = threading.Event()

        def spin() -> None:
            try:
                while not stop.is_set():
                    self.spin_once()
            except BaseException as err:  # handed to the caller
                self._spinner_errors.append(err)

        self._spinner_errors = []
        self._spinner = threading.Thread(target=spin, name="client-spin", daemon=True)
        self._spinner.start()
        try:
            yield
        finally:
            stop.set()
            self._spinner.join()
            self._spinner = None
        if self._spinner_errors:
            raise self._spinner_errors[0]

    def spin_for(self, seconds: float, check: Callable[[], None] | None = None) -> None:
        """Handle what comes in for ``seconds`` of wall time."""
        end = time.monotonic() + seconds
        self.spin_until(lambda: time.monotonic() >= end, seconds + 1.0, "nothing", check)

    @contextmanager
    def other_node(self, name: str) -> Iterator[Node]:
        """A second node of this client's participant, served by its executor while the
        block runs (a second publisher of a topic, a rogue commander), then destroyed."""
        node = rclpy.create_node(name, context=self.context)
        self.executor.add_node(node)
        try:
            yield node
        finally:
            self.executor.remove_node(node)
            node.destroy_node()

    # -- services and parameters ---------------------------------------------------------
    def answer(
        self,
        send: Callable[[], Future],
        timeout: float,
        what: str,
        check: Callable[[], None] | None = None,
        resend: bool = True,
    ) -> Any:
        """The result of the request ``send()`` makes, sent again each :data:`RESEND_AFTER`
        seconds without an answer when ``resend``; the first answer to any of the requests
        wins (one answered late is as good); TimeoutError naming ``what`` after ``timeout``
        seconds."""
        end = time.monotonic() + timeout
        sent: list[Future] = []

        def answered() -> bool:
            return any(future.done() for future in sent)

        while True:
            sent.append(send())
            left = end - time.monotonic()
            try:
                self.spin_until(answered, min(left, RESEND_AFTER) if resend else left, what, check)
                return next(future for future in sent if future.done()).result()
            except TimeoutError:
                if not resend or time.monotonic() >= end:
                    raise TimeoutError(
                        f"timed out after {timeout:g} s waiting for {what}"
                    ) from None

    def call_trigger(
        self,
        service: str,
        timeout: float = 10.0,
        check: Callable[[], None] | None = None,
        resend: bool = True,
    ) -> Trigger.Response:
        """Call a std_srvs/Trigger service; ``resend``: see :meth:`answer` (False for a
        service whose second call is not its first, the generator's ``~/publish``)."""
        client = self.node.create_client(Trigger, service)
        try:
            self.spin_until(client.service_is_ready, timeout, f"service {service}", check)
            return self.answer(
                lambda: client.call_async(Trigger.Request()),
                timeout,
                f"answer of {service}",
                check,
                resend,
            )
        finally:
            self.node.destroy_client(client)

    def trigger(
        self, service: str, check: Callable[[], None] | None = None, timeout: float = 10.0
    ) -> None:
        """:meth:`call_trigger`, raising RuntimeError with the answer when it failed."""
        response = self.call_trigger(service, timeout, check)
        if not response.success:
            raise RuntimeError(f"{service}: {response.message}")

    def parameter_client(
        self, node_name: str, timeout: float = 10.0, check: Callable[[], None] | None = None
    ) -> AsyncParameterClient:
        """The (cached) parameter client of a remote node, once its services are up."""
        client = self._param_clients.get(node_name)
        if client is None:
            client = AsyncParameterClient(self.node, node_name)
            self._param_clients[node_name] = client
        self.spin_until(
            client.services_are_ready, timeout, f"parameter services of {node_name}", check
        )
        return client

    def set_parameters(
        self,
        node_name: str,
        values: dict[str, Any],
        timeout: float = 10.0,
        check: Callable[[], None] | None = None,
    ) -> list[Any]:
        """Set parameters of a remote node; returns the SetParametersResult of each."""
        client = self.parameter_client(node_name, timeout, check)
        parameters = [Parameter(k, value=v) for k, v in values.items()]
        result = self.answer(
            lambda: client.set_parameters(parameters),
            timeout,
            f"set_parameters on {node_name}",
            check,
        )
        return list(result.results)

    def get_parameters(
        self,
        node_name: str,
        names: list[str],
        timeout: float = 10.0,
        check: Callable[[], None] | None = None,
    ) -> list[Any]:
        client = self.parameter_client(node_name, timeout, check)
        result = self.answer(
            lambda: client.get_parameters(names), timeout, f"get_parameters on {node_name}", check
        )
        return [parameter_value_to_python(v) for v in result.values]

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
