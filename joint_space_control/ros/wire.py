"""Serialized images of the control-path messages: numpy views straight into the CDR bytes.

A JointState with fixed names has a fixed layout on the wire (XCDR1, little endian, as
Fast DDS and the rosidl type support write it): only the stamp and the float64 values change
from one message to the next. Converting the Python message object instead costs more than
the control law (the names alone are seven strings to build or convert, and the arrays go
through Python lists), so the control path keeps one image of each message and

- publishes by writing the values into its views and handing the bytes to
  ``Publisher.publish`` (raw publishing, no conversion at all);
- receives with raw subscriptions and reads the values with ``np.frombuffer`` when the
  message has the layout of the previous one (same frame, names and array sizes: every byte
  that is not padding, a stamp or a value is compared); anything else goes the ordinary way
  (deserialize, validate) and its layout is learned for the next messages.

Every image checks itself once against the rosidl deserializer when it is built.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Callable, Sequence

import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from joint_space_control.control.controller import Step, state_row
from joint_space_control.ros.messages import JointOrder

#: Encapsulation header of a little-endian plain CDR payload.
CDR_LE = b"\x00\x01\x00\x00"
_STAMP = struct.Struct("<iI")
_F8 = np.dtype("<f8")


class _CdrWriter:
    """Builds an XCDR1 little-endian payload and remembers where each part is.

    Alignment is relative to the end of the 4-byte encapsulation header. ``fixed`` lists the
    (offset, bytes) that identify the layout (lengths, counts, characters), without padding.
    """

    def __init__(self) -> None:
        self.buf = bytearray(CDR_LE)
        self.fixed: list[tuple[int, bytes]] = [(0, CDR_LE[:2])]
        self.free: list[tuple[int, int]] = [(2, 4)]  # [start, end): options, stamp, values

    def _align(self, size: int) -> None:
        self.buf += bytes(-(len(self.buf) - 4) % size)

    def _put(self, data: bytes, fixed: bool) -> int:
        offset = len(self.buf)
        self.buf += data
        if fixed:
            self.fixed.append((offset, data))
        else:
            self.free.append((offset, len(self.buf)))
        return offset

    def uint32(self, value: int, fixed: bool = True) -> int:
        self._align(4)
        return self._put(struct.pack("<I", value), fixed)

    def string(self, text: str) -> None:
        data = text.encode() + b"\x00"
        self.uint32(len(data))
        self._put(data, True)

    def doubles(self, count: int) -> int:
        """A float64 sequence of ``count`` zeros; returns the offset of the first value."""
        self.uint32(count)
        if count:
            self._align(8)
        return self._put(bytes(8 * count), False)

    def merged_fixed(self) -> list[tuple[int, bytes]]:
        """Adjacent fixed parts joined (fewer comparisons per message)."""
        merged: list[tuple[int, bytes]] = []
        for offset, data in self.fixed:
            if merged and merged[-1][0] + len(merged[-1][1]) == offset:
                merged[-1] = (merged[-1][0], merged[-1][1] + data)
            else:
                merged.append((offset, data))
        return merged

    def spans(self) -> list[tuple[int, bytes]]:
        """Everything but the free parts, padding included (zeros here): a message written
        from the same image matches these few spans exactly."""
        spans, position = [], 0
        for start, end in sorted(self.free) + [(len(self.buf), len(self.buf))]:
            if start > position:
                spans.append((position, bytes(self.buf[position:start])))
            position = max(position, end)
        return spans


class JointStateImage:
    """One JointState layout: names, frame and array sizes fixed; stamp and values free.

    ``position``, ``velocity`` and ``effort`` are writable float64 views into the image
    (empty when that array is absent from the layout).
    """

    def __init__(
        self,
        names: Sequence[str],
        sizes: tuple[int, int, int] | None = None,
        frame_id: str = "",
    ) -> None:
        if sys.byteorder != "little":  # pragma: no cover - every supported host is
            raise RuntimeError("serialized images assume a little-endian host")
        self.names = tuple(names)
        self.frame_id = frame_id
        self.sizes = sizes = sizes or (len(self.names),) * 3
        w = _CdrWriter()
        self._stamp_offset = w.uint32(0, fixed=False)
        w.uint32(0, fixed=False)
        w.string(frame_id)
        w.uint32(len(self.names))
        for name in self.names:
            w.string(name)
        offsets = [w.doubles(size) for size in sizes]
        self.size = len(w.buf)
        self._buf = w.buf
        self._fixed = w.merged_fixed()
        self._spans = w.spans()
        self.position, self.velocity, self.effort = (
            np.frombuffer(self._buf, _F8, count=size, offset=offset)
            for offset, size in zip(offsets, sizes, strict=True)
        )
        self.offsets = offsets  # of the first value of each array
        self._check(frame_id)

    @classmethod
    def like(cls, msg: JointState) -> JointStateImage:
        """The layout of a received message."""
        sizes = (len(msg.position), len(msg.velocity), len(msg.effort))
        return cls(msg.name, sizes, msg.header.frame_id)

    def _check(self, frame_id: str) -> None:
        values = [np.arange(1, s + 1) * (k + 1.5) for k, s in enumerate(self.sizes)]
        for view, v in zip((self.position, self.velocity, self.effort), values, strict=True):
            view[:] = v
        self.set_stamp(1_234_567_890_123)
        msg = deserialize_message(self.to_bytes(), JointState)
        ok = (
            list(msg.name) == list(self.names)
            and msg.header.frame_id == frame_id
            and (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1234, 567_890_123)
            and all(
                np.array_equal(np.asarray(getattr(msg, f)), v)
                for f, v in zip(("position", "velocity", "effort"), values, strict=True)
            )
        )
        if not ok:  # pragma: no cover - a layout bug must never reach the wire
            raise RuntimeError("JointState image does not deserialize to itself")
        for view in (self.position, self.velocity, self.effort):
            view[:] = 0.0
        self.set_stamp(0)

    # -- writing ---------------------------------------------------------------------
    def set_stamp(self, ns: int) -> None:
        _STAMP.pack_into(self._buf, self._stamp_offset, *divmod(ns, 1_000_000_000))

    def to_bytes(self) -> bytes:
        """The serialized message, for ``Publisher.publish``."""
        return bytes(self._buf)

    # -- reading ---------------------------------------------------------------------
    def matches(self, raw: bytes) -> bool:
        """True when ``raw`` has this layout (every non-padding byte outside the stamp and
        the values equal). Publishers may append padding: longer is fine."""
        if len(raw) < self.size:
            return False
        for offset, data in self._spans:  # quick: padding zeroed as in our own images
            if not raw.startswith(data, offset):
                break
        else:
            return True
        for offset, data in self._fixed:  # exact: other writers leave padding undefined
            if not raw.startswith(data, offset):
                return False
        return True

    def read(self, raw: bytes, which: int) -> np.ndarray:
        """Values of array ``which`` (0 position, 1 velocity, 2 effort) of a matching
        message: a read-only view into ``raw``."""
        return np.frombuffer(raw, _F8, count=self.sizes[which], offset=self.offsets[which])

    @staticmethod
    def stamp(raw: bytes) -> int:
        sec, nsec = _STAMP.unpack_from(raw, 4)
        return sec * 1_000_000_000 + nsec


def clock_bytes(ns: int) -> bytes:
    """The serialized ``rosgraph_msgs/Clock`` at ``ns`` (its content ends where the bytes do,
    as rclpy serializes it)."""
    return CDR_LE + _STAMP.pack(*divmod(ns, 1_000_000_000))


class Float64ArrayImage:
    """A Float64MultiArray with a fixed layout (dimensions, data size); ``data`` is a
    writable float64 view into the image."""

    def __init__(self, template: Float64MultiArray, size: int) -> None:
        w = _CdrWriter()
        w.uint32(len(template.layout.dim))
        for dim in template.layout.dim:
            w.string(dim.label)
            w.uint32(dim.size)
            w.uint32(dim.stride)
        w.uint32(template.layout.data_offset)
        offset = w.doubles(size)
        self._buf = w.buf
        self.data = np.frombuffer(self._buf, _F8, count=size, offset=offset)
        self.data[:] = np.arange(size) + 0.5
        msg = deserialize_message(self.to_bytes(), Float64MultiArray)
        if msg.layout != template.layout or not np.array_equal(msg.data, self.data):
            raise RuntimeError(  # pragma: no cover - a layout bug must never reach the wire
                "Float64MultiArray image does not deserialize to itself"
            )
        self.data[:] = 0.0

    def to_bytes(self) -> bytes:
        return bytes(self._buf)


class ForwardCommandImage(Float64ArrayImage):
    """The command of ros2_control's forward command controller: a Float64MultiArray of
    efforts, no layout, ``order`` giving for each entry its index among the controlled
    joints (``command_joints``)."""

    def __init__(self, order: Sequence[int]) -> None:
        self.order = np.asarray(order, dtype=np.intp)
        super().__init__(Float64MultiArray(), len(self.order))

    def write(self, tau: np.ndarray) -> None:
        """The efforts [N·m], in the controlled joints' order, into the array's order."""
        self.data[:] = tau[self.order]


class JointStateReader:
    """Arrays of the controlled joints from raw JointState messages.

    ``fields`` picks the arrays (0 position, 1 velocity, 2 effort), of which ``optional``
    may be empty in a message (then an empty array is returned for it; any other size is
    the ordinary conversion's to judge); ``ordinary`` is the
    validating conversion of a deserialized message (it raises ``ValueError`` with the reason
    for an invalid one) and ``allow_extra`` whether names that are not controlled may appear.
    A message with the layout of the last valid one is read in place; its values are still
    checked for non-finite numbers (then the ordinary conversion reports it): every value of
    the requested arrays, those of names that are not controlled included, as the ordinary
    conversions do. Bytes that are no JointState raise ``ValueError`` too.
    """

    def __init__(
        self,
        order: JointOrder,
        fields: tuple[int, ...],
        ordinary: Callable[[JointState], tuple[np.ndarray, ...]],
        allow_extra: bool,
        optional: tuple[int, ...] = (),
    ) -> None:
        self._order = order
        self._fields = fields
        self._optional = optional
        self._present = fields  # the requested fields the learned layout carries
        self._ordinary = ordinary
        self._allow_extra = allow_extra
        self._image: JointStateImage | None = None
        self._base = 0  # offset of the first requested value
        self._span = 0  # float64 slots from there to the last requested value
        self._index: np.ndarray | None = None  # slots of the requested values, in order
        # slots of every value of those arrays, when some are not requested (extra names)
        self._checked: np.ndarray | None = None
        #: ``header.frame_id`` of the message read last (its sender's claim, see sim_bridge)
        self.frame_id = ""

    def read(self, raw: bytes) -> tuple[int, tuple[np.ndarray, ...]]:
        """(stamp [ns], arrays in the controlled-joint order); raises ``ValueError``.
        ``frame_id`` is then the message's ``header.frame_id``."""
        image = self._image
        if image is not None and image.matches(raw):  # the layout includes the frame_id
            self.frame_id = image.frame_id
            block = np.frombuffer(raw, _F8, count=self._span, offset=self._base)
            values = block[self._index]
            checked = values if self._checked is None else block[self._checked]
            if np.isfinite(checked).all():
                arrays = tuple(values.reshape(len(self._present), -1))
                if self._present is not self._fields:  # an optional array is absent
                    arrays = self._with_absent(arrays)
                return JointStateImage.stamp(raw), arrays
        try:
            msg = deserialize_message(raw, JointState)
        except RuntimeError as err:  # rmw's RMWError: truncated or garbled bytes
            raise ValueError(f"not a serialized JointState ({len(raw)} bytes): {err}") from None
        self.frame_id = msg.header.frame_id
        arrays = self._ordinary(msg)
        self._learn(msg)
        stamp = msg.header.stamp
        return stamp.sec * 1_000_000_000 + stamp.nanosec, arrays

    def _with_absent(self, arrays: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        present = iter(arrays)
        return tuple(next(present) if f in self._present else np.empty(0) for f in self._fields)

    def _learn(self, msg: JointState) -> None:
        """Read the next messages of this layout in place."""
        image = JointStateImage.like(msg)
        joints = self._order.index(msg.name, allow_extra=self._allow_extra)
        present = tuple(f for f in self._fields if image.sizes[f] or f not in self._optional)
        self._present = self._fields if present == self._fields else present
        offsets = [image.offsets[f] for f in present]
        self._base = min(offsets)
        firsts = [(offset - self._base) // 8 for offset in offsets]
        self._index = np.concatenate([first + joints for first in firsts])
        checked = np.concatenate(
            [first + np.arange(image.sizes[f]) for first, f in zip(firsts, present, strict=True)]
        )
        self._checked = None if checked.size == self._index.size else checked
        self._span = int(checked.max()) + 1
        self._image = image


def fill_images(
    command: JointStateImage | ForwardCommandImage,
    state: Float64ArrayImage | None,
    stamp_ns: int,
    step: Step,
) -> None:
    """Write a step's command (:attr:`~joint_space_control.control.controller.Step.sent`)
    into the command image (effort, stamp of the state it answers; or the array) and, when
    given, the ``~/state`` image (README "Controller state": q_d, q̇_d, q̈_d, q, q̇, e, ė,
    τ feedback/model/gravity, τ before and after clamping), with the reference and the
    state (q, q̇ measured or estimated) the law used."""
    if isinstance(command, JointStateImage):
        command.effort[:] = step.sent
        command.set_stamp(stamp_ns)
    else:  # an array without a stamp, in its own joint order
        command.write(step.sent)
    if state is None:
        return
    data = state.data
    data[0] = stamp_ns * 1e-9
    state_row(step, out=data[1:])
