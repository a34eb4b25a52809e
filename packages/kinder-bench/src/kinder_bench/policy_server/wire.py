"""msgpack with numpy arrays, in openpi's ``msgpack_numpy`` layout.

An ndarray travels as ``{"__ndarray__": True, "data": bytes, "dtype": dtype.str, "shape": shape}``
and a numpy scalar as ``{"__npgeneric__": True, "data": item, "dtype": dtype.str}``; object, void
and complex dtypes are refused, as openpi does. Written here rather than depending on
``openpi-client``, which pins ``numpy<2``.
"""

from __future__ import annotations

from typing import Any

import msgpack
import numpy as np

_REFUSED_KINDS = ("V", "O", "c")


def _encode(obj: Any) -> Any:
    if isinstance(obj, np.ndarray | np.generic) and obj.dtype.kind in _REFUSED_KINDS:
        raise ValueError(f"cannot send arrays of dtype {obj.dtype} (object, void and complex)")
    if isinstance(obj, np.ndarray):
        return {
            b"__ndarray__": True,
            b"data": np.ascontiguousarray(obj).tobytes(),
            b"dtype": obj.dtype.str,
            b"shape": list(obj.shape),
        }
    if isinstance(obj, np.generic):
        return {b"__npgeneric__": True, b"data": obj.item(), b"dtype": obj.dtype.str}
    return obj


def _decode(obj: dict[Any, Any]) -> Any:
    if b"__ndarray__" in obj:
        return np.frombuffer(obj[b"data"], dtype=np.dtype(obj[b"dtype"])).reshape(obj[b"shape"])
    if b"__npgeneric__" in obj:
        return np.dtype(obj[b"dtype"]).type(obj[b"data"])
    return obj


def packb(obj: Any) -> bytes:
    """Serialise ``obj`` (dicts, lists, scalars, strings, numpy arrays) to msgpack bytes."""
    data: bytes = msgpack.packb(obj, default=_encode, use_bin_type=True)
    return data


def unpackb(data: bytes) -> Any:
    """The inverse of :func:`packb`; raises ``ValueError`` on bytes that are not valid msgpack."""
    try:
        return msgpack.unpackb(data, object_hook=_decode, raw=False)
    except (msgpack.UnpackException, ValueError, TypeError, KeyError) as e:
        raise ValueError(f"not a valid msgpack-numpy message ({type(e).__name__}: {e})") from e
