"""Plain-JSON encoding for the policy format: Gymnasium spaces, float lists with ±inf, strict dumps.

Everything here turns objects into JSON values and back without ``eval`` or pickle; a value that is
not plain data (a class, a function, NaN) is refused rather than written.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["PolicyFormatError", "dump_json", "finite_or_none", "floats_from_json", "floats_to_json", "json_value",
           "space_from_json", "space_to_json"]

_JSON_SCALARS = (bool, int, float, str, type(None))


class PolicyFormatError(ValueError):
    """A policy directory or file is missing, malformed, or does not describe a loadable policy."""


def floats_to_json(a: np.ndarray) -> list[Any]:
    """Numbers as a flat JSON list; ±inf and NaN as the strings "inf", "-inf", "nan"."""
    return [v if math.isfinite(v) else ("inf" if v > 0 else "-inf" if v < 0 else "nan") for v in
            np.asarray(a, dtype=np.float64).reshape(-1).tolist()]


def floats_from_json(values: Any, where: str) -> np.ndarray:
    """Inverse of :func:`floats_to_json` (``where`` names the field in errors)."""
    if not isinstance(values, list):
        raise PolicyFormatError(f"{where} must be a list of numbers")
    out = []
    for v in values:
        if isinstance(v, str) and v in ("inf", "-inf", "nan"):
            out.append(float(v))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(float(v))
        else:
            raise PolicyFormatError(f"{where} must hold numbers, got {v!r}")
    return np.asarray(out, dtype=np.float64)


def space_to_json(space: Any) -> dict[str, Any]:
    """A Gymnasium ``Box`` or ``Discrete`` as plain JSON (±inf bounds as the strings "inf"/"-inf")."""
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return {"type": "Box", "shape": list(space.shape), "dtype": str(space.dtype),
                "low": floats_to_json(space.low), "high": floats_to_json(space.high)}
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    raise PolicyFormatError(f"cannot export a {type(space).__name__} space (only Box and Discrete)")


def space_from_json(d: Any, where: str = "space") -> Any:
    """Inverse of :func:`space_to_json`."""
    from gymnasium import spaces

    if not isinstance(d, dict) or d.get("type") not in ("Box", "Discrete"):
        raise PolicyFormatError(f"{where} must be an object with type 'Box' or 'Discrete', got {d!r}")
    if d["type"] == "Discrete":
        n, start = d.get("n"), d.get("start", 0)
        if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1 and isinstance(start, int)):
            raise PolicyFormatError(f"{where}: Discrete needs an integer n ≥ 1 and an integer start")
        return spaces.Discrete(n, start=start)
    shape = d.get("shape")
    if not (isinstance(shape, list) and shape and all(isinstance(s, int) and s >= 1 for s in shape)):
        raise PolicyFormatError(f"{where}: Box shape must be a list of positive integers, got {shape!r}")
    if d.get("dtype") not in ("float32", "float64"):
        raise PolicyFormatError(f"{where}: Box dtype must be float32 or float64, got {d.get('dtype')!r}")
    low = floats_from_json(d.get("low"), f"{where}.low")
    high = floats_from_json(d.get("high"), f"{where}.high")
    size = int(np.prod(shape))
    if low.size != size or high.size != size:
        raise PolicyFormatError(f"{where}: low/high must have {size} values for shape {shape}")
    dtype = np.dtype(d["dtype"])
    return spaces.Box(low.reshape(shape).astype(dtype), high.reshape(shape).astype(dtype), dtype=dtype)


def json_value(value: Any, where: str) -> Any:
    """``value`` as plain JSON data (tuples → lists); anything else (classes, NaN) is refused."""
    if isinstance(value, _JSON_SCALARS):
        if isinstance(value, float) and not math.isfinite(value):
            raise PolicyFormatError(f"cannot export {where} = {value!r} (not finite)")
        return value
    if isinstance(value, (list, tuple)):
        return [json_value(v, where) for v in value]
    if isinstance(value, Mapping):
        return {str(k): json_value(v, f"{where}.{k}") for k, v in value.items()}
    raise PolicyFormatError(f"cannot export {where} = {value!r} (not plain data)")


def dump_json(obj: Any, indent: int = 0) -> str:
    """Strict JSON (no NaN), objects one key per line, lists of plain values on one line."""
    pad = " " * (indent + 2)
    if isinstance(obj, dict) and obj:
        items = [f"{pad}{json.dumps(str(k))}: {dump_json(v, indent + 2)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"
    if isinstance(obj, list) and any(isinstance(v, (dict, list)) for v in obj):
        return "[\n" + ",\n".join(pad + dump_json(v, indent + 2) for v in obj) + "\n" + " " * indent + "]"
    return json.dumps(obj, allow_nan=False, ensure_ascii=False)


def finite_or_none(row: Mapping[str, Any]) -> dict[str, Any]:
    """A flat mapping with non-finite floats replaced by None."""
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}
