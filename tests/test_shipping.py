"""What the loops and the sweep send to Dask workers arrives with every array in
aligned memory of its own (:class:`qsma._infra.shipping.InBand`), wherever the
transport places the frames it received: a BLAS wrapper copies a misaligned matrix on
every call (the loops of lap-3d took four times their time on a Dask worker)."""
from __future__ import annotations

import numpy as np
import pytest

from qsma._infra.shipping import InBand
from qsma.contact import ContactProblem


def _at_offset(frames, offset):
    """Each frame copied to ``offset`` bytes past an allocation, as a transport that
    reads several frames into one buffer leaves them."""
    out = []
    for f in frames:
        raw = memoryview(f).cast("B")
        buf = bytearray(len(raw) + offset)
        buf[offset:] = raw
        out.append(memoryview(buf)[offset:])
    return out


def _arrays(obj):
    p = obj["problem"]
    return [p.K, p.diagonal_blocks, obj["status"], obj["W"]]


@pytest.mark.parametrize("offset", [1, 3, 5])
def test_arrays_arrive_aligned_and_owned_whatever_the_frame_offset(offset):
    protocol = pytest.importorskip("distributed.protocol.serialize")
    rng = np.random.default_rng(1)
    A = rng.standard_normal((60, 60))
    obj = {"problem": ContactProblem(A @ A.T + 60 * np.eye(60), 0.3),
           "status": np.arange(20, dtype=np.int8), "W": rng.standard_normal((60, 2)).T}
    header, frames = protocol.serialize_and_split(InBand(obj))
    received = _at_offset(frames, offset)
    got = protocol.merge_and_deserialize(header, received)
    assert isinstance(got, dict)                    # the object itself, not the wrapper
    for before, after in zip(_arrays(obj), _arrays(got)):
        assert after.flags.aligned
        assert not any(np.shares_memory(after, np.frombuffer(f, np.uint8))
                       for f in received)
        assert np.array_equal(before, after) and after.dtype == before.dtype
    plain_header, plain = protocol.serialize_and_split(obj)
    plain = protocol.merge_and_deserialize(plain_header, _at_offset(plain, offset))
    # what InBand prevents: sent as it is, a matrix is a view into a misplaced frame
    assert not plain["problem"].K.flags.aligned


def test_the_solves_of_a_shipped_problem_give_the_same_bits():
    """Sent in band, a contact problem solves as the original: the same bits."""
    import pickle
    from qsma.contact import solve
    rng = np.random.default_rng(2)
    A = rng.standard_normal((30, 30))
    problem = ContactProblem(A @ A.T + 30 * np.eye(30), 0.4)
    lam_w = rng.standard_normal((15, 2))
    there = pickle.loads(pickle.dumps(InBand(problem)))
    a, b = solve(problem, lam_w), solve(there, lam_w)
    assert a.success and b.success
    assert np.array_equal(a.lam, b.lam) and np.array_equal(a.d, b.d)
    assert np.array_equal(a.status, b.status)
