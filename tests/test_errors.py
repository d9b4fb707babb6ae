"""``errors.ctrl_c_inside``: a Ctrl-C wrapped by a compiled call is still a Ctrl-C."""

from __future__ import annotations

from sigma_des.errors import ctrl_c_inside


def _wrapped() -> BaseException:
    """What numba raises when a Ctrl-C lands in its own Python code: a SystemError whose
    cause is an error whose context is the KeyboardInterrupt."""
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as k:
            raise SystemError("returned a result with an exception set") from k
    except SystemError as s:
        try:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") from s
        except SystemError as outer:
            return outer


def test_a_keyboard_interrupt_anywhere_in_the_chain_counts() -> None:
    assert ctrl_c_inside(KeyboardInterrupt())
    assert ctrl_c_inside(_wrapped())


def test_other_errors_do_not_count_and_a_cyclic_chain_ends() -> None:
    assert not ctrl_c_inside(SystemError("x"))
    try:
        try:
            raise ValueError("a")
        except ValueError as a:
            raise SystemError("b") from a
    except SystemError as b:
        assert not ctrl_c_inside(b)
    e = ValueError("self")
    e.__context__ = e  # a cycle: the walk stops
    assert not ctrl_c_inside(e)
