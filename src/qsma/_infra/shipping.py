"""Objects sent to the workers of a Dask scheduler with every array in aligned memory
of its own.

Dask pickles what it sends with protocol 5 and carries the numpy buffers out of band;
a worker rebuilds the arrays as views into the frames it received, at whatever offset
each buffer landed, which need not be a multiple of 8 bytes. Such an array works, but
a BLAS call through scipy's wrappers copies a misaligned matrix on every call and
numpy's loops take their slow path: the loops of lap-3d took four times their time on
a Dask worker, the dense interface stiffness copied at each of its products
(``python benchmarks/bench_loops.py parallel``). Sent as :class:`InBand`, the object
is pickled with protocol 4, whose arrays travel inside the pickle and are unpickled
into memory numpy allocates (aligned, owned) on the worker.
"""
from __future__ import annotations

import pickle

#: The pickle protocol of :class:`InBand`: the newest that keeps numpy's buffers in
#: band (protocol 5 hands them to the transport, which places them).
PROTOCOL = 4


class InBand:
    """``obj`` as sent to a Dask worker (``client.scatter(InBand(obj))``): it arrives as
    ``obj`` itself, every array of it copied into memory of its own."""

    __slots__ = ("obj",)

    def __init__(self, obj):
        self.obj = obj

    def __reduce__(self):
        return pickle.loads, (pickle.dumps(self.obj, protocol=PROTOCOL),)
