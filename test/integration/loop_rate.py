"""The rate of the realtime loop in the tests that run one beside heavy work of their own
(a browser drawing the page, the fault soak's recorder, dashboard and faults).

The loop's nodes are Python: how fast a machine runs Python decides whether a 1 kHz loop
keeps up beside that work on two cores. On the machines where the 1 kHz fault soak passed
its hour, ``sum(range(1000))`` takes about 10 µs; on a VM that ran it in 28–43 µs, the 1 kHz
short fault soak failed on every kind (the controller a hundred milliseconds behind the
plant, braked again and again) and passed at 250 Hz with 1.9 of 2 cores busy
(docs/safety.md, "On a slower machine"). On that VM, at 29-37 µs, the page test failed at
250 Hz, alone and in CI: the controller (~40 % of a core at 250 Hz) fell behind the plant
hundreds of times beside Chromium, and the page waited 120 s for a redraw; at 100 Hz the
controller took ~23 % of a core and the same test passed in 217 s. So these tests run the
loop at 1 kHz on a machine as fast as those of the 1 kHz hours, at 250 Hz on one up to
twice slower, and at 100 Hz on a slower one; what they judge (faults survived, the page and
the loop) does not depend on the rate. ``JSC_TEST_LOOP_RATE`` sets the rate instead.
"""

from __future__ import annotations

import functools
import os

from joint_space_control.machine import python_speed_us

#: (``sum(range(1000))`` at most this slow [µs], the loop's rate there [Hz]), fastest first;
#: each rate a divisor of the plant's 1 kHz physics.
RATES = ((15.0, 1000.0), (20.0, 250.0))
#: The rate on a machine slower than every entry of :data:`RATES` [Hz].
SLOWEST_RATE = 100.0
#: The least rate of a test that runs the plant alone, without a controller or a browser
#: [Hz]: it kept up at 250 Hz on the slowest machine seen (test_probe_catches_up.py).
PLANT_ALONE_RATE = 250.0


def rate_for(speed_us: float) -> float:
    """The loop's rate [Hz] on a machine that runs ``sum(range(1000))`` in ``speed_us``."""
    return next((rate for slowest, rate in RATES if speed_us <= slowest), SLOWEST_RATE)


@functools.cache
def loop_rate() -> float:
    """The realtime loop's rate for this machine [Hz] (:func:`rate_for`; measured once per
    test process, printed with the yardstick)."""
    chosen = os.environ.get("JSC_TEST_LOOP_RATE")
    if chosen:
        return float(chosen)
    speed = python_speed_us()
    rate = rate_for(speed)
    print(f"\nloop rate {rate:g} Hz: sum(range(1000)) in {speed:.1f} µs on this machine")
    return rate
