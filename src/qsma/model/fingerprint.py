"""A fingerprint of what a model is: every field of its dataclasses, array contents
included.

A parameter study resumes the cases of a folder only when the model is the one they
were computed from; two models with the same set *names* but other set *contents*
(a clamp of other nodes, a bolt surface halved) give other answers. The fingerprint
therefore walks the model's dataclasses field by field (bodies, meshes with every
node, facet and cell set, materials, clamps, loads, springs, interfaces, probe,
bolts), so a field added to one of them later is covered without being listed here.
"""
from __future__ import annotations

import dataclasses
import hashlib

import numpy as np


def fingerprint(obj) -> str:
    """SHA-256 (hex) of ``obj``: dataclasses field by field, arrays by dtype, shape and
    bytes, mappings by sorted key, sequences in order, scalars by type and ``repr``
    (floats round-trip exactly)."""
    h = hashlib.sha256()
    _feed(h, obj)
    return h.hexdigest()


def _feed(h, obj):
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(f"<{type(obj).__qualname__}:".encode())
        for f in dataclasses.fields(obj):
            h.update(f.name.encode() + b"=")
            _feed(h, getattr(obj, f.name))
        h.update(b">")
    elif isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"<array {a.dtype.str} {a.shape}:".encode())
        h.update(a.tobytes())
        h.update(b">")
    elif isinstance(obj, dict):
        h.update(f"<dict {len(obj)}:".encode())
        for key in sorted(obj, key=repr):
            _feed(h, key)
            _feed(h, obj[key])
        h.update(b">")
    elif isinstance(obj, (list, tuple)):
        h.update(f"<{type(obj).__name__} {len(obj)}:".encode())
        for item in obj:
            _feed(h, item)
        h.update(b">")
    elif isinstance(obj, np.generic):
        _feed(h, obj.item())
    else:
        h.update(f"<{type(obj).__name__} {obj!r}>".encode())
