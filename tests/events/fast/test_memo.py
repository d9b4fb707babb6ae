"""``IdentityMemo``: results kept per identity of the objects (never per equal value),
bounded; and the two memoised derivations of a run spec give what computing them gives."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import tables
from sigma_des.events.fast.memo import IdentityMemo
from sigma_des.events.fast.support import check_support, unsupported
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny


def test_results_are_kept_per_identity_and_values() -> None:
    memo: IdentityMemo[int] = IdentityMemo(size=2)
    calls: list[int] = []

    def make(v: int) -> int:
        calls.append(v)
        return v

    a, b = [1], [1]  # equal, not the same object
    assert memo.get((a,), 0, lambda: make(1)) == 1
    assert memo.get((a,), 0, lambda: make(2)) == 1  # kept
    assert memo.get((b,), 0, lambda: make(3)) == 3  # another object: computed
    assert memo.get((a,), 1, lambda: make(4)) == 4  # other values: computed, a's 0 dropped
    assert memo.get((a,), 0, lambda: make(5)) == 5
    assert calls == [1, 3, 4, 5]


def test_support_and_deployment_tables_as_computed() -> None:
    sc = replace(tiny(**{"net.host_link.loss": {"p": 0.1}}), engine="cohort")
    spec = sc.run_spec()
    for method in ("bides", "rpc"):
        assert unsupported(spec, method) == check_support(spec, method)
        assert unsupported(replace(spec, seed=5), method) == check_support(spec, method)
    assert unsupported(spec, "rpc") is not None and unsupported(spec, "bides") is None
    run = MethodRun(spec, "bides", make_dynamics(sc), make_behaviour(sc), compiled=True)
    want = tables._deployment_tables(run.net, spec)
    one = tables.deployment_tables(run.net, spec)
    one["cpu_proc"][:] = 99  # a run's copy: the kept tables do not see the write
    two = tables.deployment_tables(run.net, spec)
    assert sorted(two) == sorted(want)
    for k, v in want.items():
        assert two[k].dtype == v.dtype and np.array_equal(two[k], v)
