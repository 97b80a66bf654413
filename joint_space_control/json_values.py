"""Values made ready for strict JSON: the one conversion every JSON file and message uses.

``json.dumps`` neither knows numpy values nor writes standard JSON for NaN and infinities
(it writes the non-standard tokens ``NaN`` and ``Infinity`` that strict parsers, browsers
and ``jq`` reject). Results here hold both: metrics of a response that never settles are
NaN, a joint without limits has infinite bounds, arrays come from numpy and parameters from
rclpy as ``array.array``. :func:`jsonable` maps all of them to plain Python values once, so
that ``json.dumps(jsonable(x), allow_nan=False)`` cannot fail on them and every writer
(``~/config``, ``metrics.json``, ``bench.json``, ``soak.json``) agrees on what a missing
number looks like: ``null``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


def jsonable(value: Any) -> Any:
    """``value`` as plain Python values that encode as strict JSON.

    - numpy arrays and scalars, ``array.array`` (what rclpy hands out for a double array
      parameter): their ``tolist()``, i.e. Python lists, floats, ints and bools;
    - mappings: dicts with ``str`` keys; lists and tuples: lists;
    - NaN and ±inf: ``None`` (JSON ``null``);
    - ``None``, ``bool``, ``int``, ``str`` (and their subclasses, e.g. ``StrEnum`` members):
      unchanged;
    - anything else (bytes, paths, ...): its ``str``, so a message or file is still written.
    """
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, bool | int | str):
        return value
    return str(value)
