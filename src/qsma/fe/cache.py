"""Per-mesh caches that live exactly as long as their mesh.

Element spaces, quadrature data and sparsity patterns are built once per mesh and
reused by every assembly of it (stiffness and mass, a sweep's material cases). A
:func:`functools.lru_cache` keyed on the mesh would keep the last meshes of a process
alive together with those arrays, however many runs ago they were used: a program
running several models in turn kept the element data of up to eight meshes of
earlier runs (docs/performance.md, "Memory of repeated runs in one process"). Here
the mesh is held weakly: its entries go when the mesh is collected, and a mesh that
lives is never rebuilt.
"""
from __future__ import annotations

import functools
import threading
import weakref


def per_mesh(function):
    """Decorator: cache ``function(mesh, *args)`` by ``mesh`` (held weakly, by
    identity; meshes are immutable) and ``args`` (hashable).

    The cached values must not refer to ``mesh`` itself, else the entry keeps its key
    alive. ``cached.cache_clear()`` empties the cache; ``cached.cache_size()`` is the
    number of meshes held.
    """
    store = weakref.WeakKeyDictionary()
    lock = threading.Lock()

    @functools.wraps(function)
    def cached(mesh, *args):
        with lock:
            entries = store.get(mesh)
            if entries is not None and args in entries:
                return entries[args]
        value = function(mesh, *args)
        with lock:
            return store.setdefault(mesh, {}).setdefault(args, value)

    def cache_clear():
        with lock:
            store.clear()

    cached.cache_clear = cache_clear
    cached.cache_size = lambda: len(store)
    return cached


__all__ = ["per_mesh"]
