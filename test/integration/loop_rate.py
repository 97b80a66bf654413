"""The rate of the realtime loop in the tests that run one beside heavy work of their own
(a browser drawing the page, the fault soak's recorder, dashboard and faults).

The loop's nodes are Python: how fast a machine runs Python decides whether a 1 kHz loop
keeps up beside that work on two cores. On the machines where the 1 kHz fault soak passed
its hour, ``sum(range(1000))`` takes about 10 µs; on a VM that ran it in 28–43 µs, the 1 kHz
short fault soak failed on every kind (the controller a hundred milliseconds behind the
plant, braked again and again) and passed at 250 Hz with 1.9 of 2 cores busy
(docs/safety.md, "On a slower machine"). So these tests run the loop at 1 kHz on a machine
as fast as those, and at 250 Hz on a slower one; what they judge (faults survived, the page
and the loop) does not depend on the rate. ``JSC_TEST_LOOP_RATE`` sets the rate instead.
"""

from __future__ import annotations

import functools
import os

from joint_space_control.machine import python_speed_us

#: ``sum(range(1000))`` at most this slow [µs]: a machine like those of the 1 kHz hours.
FAST_ENOUGH_US = 15.0
#: The rate on a slower machine [Hz] (a divisor of the plant's 1 kHz physics).
SLOW_MACHINE_RATE = 250.0


@functools.cache
def loop_rate() -> float:
    """The realtime loop's rate for this machine [Hz]: 1000 or :data:`SLOW_MACHINE_RATE`
    (measured once per test process, printed with the yardstick)."""
    chosen = os.environ.get("JSC_TEST_LOOP_RATE")
    if chosen:
        return float(chosen)
    speed = python_speed_us()
    rate = 1000.0 if speed <= FAST_ENOUGH_US else SLOW_MACHINE_RATE
    print(f"\nloop rate {rate:g} Hz: sum(range(1000)) in {speed:.1f} µs on this machine")
    return rate
