"""The one strict-JSON conversion (``~/config``, metrics.json, bench.json, soak.json)."""

from __future__ import annotations

import array
import json
from pathlib import Path

import numpy as np

from joint_space_control.json_values import jsonable


def test_numpy_python_and_non_finite_values_become_strict_json():
    value = {
        1: np.float32("nan"),
        "rows": [{"x": np.float64(0.25), "n": np.int32(7)}, (np.inf, -np.inf)],
        "flags": np.array([True, False]),
        "params": array.array("d", [1.5, float("nan")]),
        "path": Path("/tmp/x"),
        "none": None,
    }
    plain = jsonable(value)
    assert plain == {
        "1": None,
        "rows": [{"x": 0.25, "n": 7}, [None, None]],
        "flags": [True, False],
        "params": [1.5, None],
        "path": "/tmp/x",
        "none": None,
    }
    assert type(plain["rows"][0]["n"]) is int and type(plain["flags"][0]) is bool
    json.dumps(plain, allow_nan=False)  # raises on a NaN token
