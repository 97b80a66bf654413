"""Whether two engines gave the same experiment: the check texts and the run metrics, bit for
bit, apart from what only the recording's clock decides.

A lockstep run does not depend on timing, so the ROS engine and the in-process engine
(:mod:`~joint_space_control.workbench.experiments.execution.inprocess`) must agree to the last bit
on
every metric of the control (errors, overshoot, settling, torque demand, the configuration in
force) and on every check's text. What legitimately differs is what the bag's log times
and its bookkeeping say: the recorder's receive times on ROS (wall clock) against the
simulated times in process, and the wall-time topics only the recorder takes
(``/diagnostics``, ``/parameter_events``). Those keys are :data:`RECORDING_KEYS`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

#: Metrics that describe the recording rather than the run (left out of the comparison).
RECORDING_KEYS = frozenset(
    {
        "bag",
        "storage",
        "start_time_ns",
        "duration_s",
        "message_count",
        "message_counts",
        "topic_types",
        "receive_period_ms",
    }
)


def differences(a: Any, b: Any, path: str = "") -> list[str]:
    """Where ``a`` and ``b`` (JSON values) differ, as ``path: a != b`` lines; NaN equals
    NaN; keys in :data:`RECORDING_KEYS` are skipped at any depth."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            if key in RECORDING_KEYS:
                continue
            if key not in a or key not in b:
                out.append(f"{path}/{key}: only in {'the first' if key in a else 'the second'}")
            else:
                out += differences(a[key], b[key], f"{path}/{key}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items != {len(b)}"]
        return [
            d
            for k, (x, y) in enumerate(zip(a, b, strict=True))
            for d in differences(x, y, f"{path}[{k}]")
        ]
    both_nan = isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)
    return [] if a == b or both_nan else [f"{path}: {a!r} != {b!r}"]


def compare_experiments(first: Path, second: Path) -> list[str]:
    """The differences between one experiment's directories (``out/<name>``) of two runs:
    its check texts, verdicts and numbers (``result.json``), and each run's metrics
    (``report/metrics.json``). Empty when they agree."""
    a = json.loads((first / "result.json").read_text())
    b = json.loads((second / "result.json").read_text())
    out = differences(
        [(c["check"], c["passed"], c["text"], c.get("numbers")) for c in a["checks"]],
        [(c["check"], c["passed"], c["text"], c.get("numbers")) for c in b["checks"]],
        "checks",
    )
    out += differences(a["errors"], b["errors"], "errors")
    runs_a = {r["label"]: Path(r["dir"]) for r in a["runs"]}
    runs_b = {r["label"]: Path(r["dir"]) for r in b["runs"]}
    if list(runs_a) != list(runs_b):
        return [*out, f"runs: {list(runs_a)} != {list(runs_b)}"]
    for label, run_a in runs_a.items():
        metrics_a = json.loads((run_a / "report" / "metrics.json").read_text())
        metrics_b = json.loads((runs_b[label] / "report" / "metrics.json").read_text())
        out += differences(metrics_a, metrics_b, f"{label}:metrics")
    return out
