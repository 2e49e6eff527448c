"""`rhi.design.executors.shared`: one default executor for every map of a reproduction."""

from __future__ import annotations

from rhi.design import executors as ex


def test_shared_default_executor_is_reused_then_closed(monkeypatch):
    closed = []

    class Spy(ex.SerialExecutor):
        def close(self) -> None:
            closed.append(self)

    monkeypatch.setattr(ex, "default_executor", Spy)
    with ex.shared() as sh:
        with ex.using() as a, ex.using() as b:
            assert a is sh and b is sh
        assert ex.parallel_map(abs, [-1, 2, -3]) == [1, 2, 3]
        with ex.using("serial") as own:  # an explicit choice still gets its own executor
            assert own is not sh
        assert closed == []  # maps inside the block leave the shared executor open
    assert closed == [sh]
    with ex.using() as c:
        assert c is not sh
    assert closed[-1] is c
