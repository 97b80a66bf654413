"""RosClient.answer: a request whose answer a service dropped (rmw_fastrtps drops it when it
has not yet matched the client's reply reader) is sent again, and the first answer wins;
a service whose second call differs (resend=False) is called once."""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest
from rclpy.task import Future

from joint_space_control.processes import client as client_module
from joint_space_control.processes.client import RosClient

RESEND = 0.05  # [s] instead of RESEND_AFTER, for a quick test


class Service:
    """Answers the request numbered ``answered`` (1-based) and drops the others; with
    ``late``, that answer comes only when the next request goes out."""

    def __init__(self, answered: int | None, late: bool = False) -> None:
        self.answered = answered
        self.late = late
        self.sent: list[Future] = []

    def send(self) -> Future:
        self.sent.append(Future())
        number = len(self.sent) - 1 if self.late else len(self.sent)
        if number == self.answered:
            self.sent[number - 1].set_result(f"answer to request {number}")
        return self.sent[-1]


class Caller:
    """RosClient.answer on a client whose spinning is a wait (nothing to serve here)."""

    answer = RosClient.answer

    def spin_until(
        self, done: Callable[[], bool], timeout: float, what: str, check: object = None
    ) -> None:
        end = time.monotonic() + timeout
        while not done():
            if time.monotonic() > end:
                raise TimeoutError(f"timed out after {timeout:g} s waiting for {what}")
            time.sleep(0.001)


@pytest.fixture(autouse=True)
def quick_resend(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(client_module, "RESEND_AFTER", RESEND)


def test_a_dropped_answer_is_asked_for_again():
    service = Service(answered=3)
    assert Caller().answer(service.send, 5.0, "an answer") == "answer to request 3"
    assert len(service.sent) == 3


def test_an_answer_that_comes_late_is_taken_though_the_request_was_sent_again():
    service = Service(answered=1, late=True)
    assert Caller().answer(service.send, 5.0, "an answer") == "answer to request 1"
    assert len(service.sent) == 2


def test_an_answered_request_is_sent_once():
    service = Service(answered=1)
    assert Caller().answer(service.send, 5.0, "an answer") == "answer to request 1"
    assert len(service.sent) == 1


def test_no_answer_times_out_naming_what_and_the_whole_timeout():
    service = Service(answered=None)
    start = time.monotonic()
    with pytest.raises(TimeoutError, match=r"timed out after 0\.3 s waiting for the pause"):
        Caller().answer(service.send, 0.3, "the pause")
    assert time.monotonic() - start >= 0.3
    assert len(service.sent) >= 0.3 / RESEND - 1


def test_without_resend_the_request_is_sent_once_and_waited_for_whole():
    service = Service(answered=2)
    with pytest.raises(TimeoutError, match=r"after 0\.2 s waiting for the publish"):
        Caller().answer(service.send, 0.2, "the publish", resend=False)
    assert len(service.sent) == 1
