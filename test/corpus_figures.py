"""The corpus closed-loop figures of docs/robots.md, from the runs the tests check
(test/unit/test_corpus.py): PD + g(q) on the controller's defaults, a 0.05 rad step, on each
engine in lockstep.

    python -m test.corpus_figures      # from the repository root, ~8 s

prints the Markdown table's rows.
"""

from __future__ import annotations

import numpy as np

from sim_bridge.engines import ENGINES
from test.corpus import CORPUS
from test.unit.test_corpus import REFUSED, STEP_DURATION, default_pd_gravity_step

LABELS = {"pybullet": "PyBullet", "mujoco": "MuJoCo"}
WITHIN = 1e-3  # [rad] for the settling column


def rows() -> list[str]:
    """One Markdown row per corpus robot: per engine, the error at the end [rad] and the
    largest |τ| / effort limit; then the engines' largest position difference [rad] and the
    time from which the error stays below WITHIN [s] (the first engine that ran it)."""
    lines = []
    for robot in CORPUS:
        runs = {
            engine: default_pd_gravity_step(robot.name, engine)
            for engine in ENGINES
            if (robot.name, engine) not in REFUSED
        }
        cells = [robot.name]
        for engine in ENGINES:
            run = runs.get(engine)
            cells += (
                [f"{run.final_error:.1e}", f"{run.effort_ratio:.3f}"]
                if run
                else ["refused", "refused"]
            )
        if len(runs) == len(ENGINES):
            q = [run.q for run in runs.values()]
            cells.append(f"{max(float(np.max(np.abs(a - q[0]))) for a in q[1:]):.1e}")
        else:
            cells.append("—")
        cells.append(f"{next(iter(runs.values())).settled_from(WITHIN):.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    header = ["robot"]
    for engine in ENGINES:
        header += [
            f"{LABELS[engine]}: error after {STEP_DURATION:g} s [rad]",
            f"{LABELS[engine]}: max \\|τ\\|/limit",
        ]
    header += ["max \\|q_MuJoCo − q_PyBullet\\| [rad]", f"stays within {WITHIN:g} rad from [s]"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    print("\n".join(rows()))


if __name__ == "__main__":
    main()
