"""The second Ctrl-C of ``elastoflow run`` stops at once, except inside Numba's compiler or
cache loader: an exception raised there lands in an llvmlite ctypes callback and the process
died of SIGSEGV (a double Ctrl-C during the first step, seen in the fault tests)."""

from __future__ import annotations

import signal
import sys
import time

import pytest

from elastoflow.cli import _StopRequest


def _signal_in(filename: str, stop: _StopRequest) -> None:
    """Deliver SIGINT to ``stop``'s handler as if Python code of ``filename`` was running."""
    code = compile("handler(signal.SIGINT, sys._getframe())", filename, "exec")
    exec(code, {"handler": stop._handle, "signal": signal, "sys": sys})  # noqa: S102


def test_the_second_ctrl_c_stops_at_once_in_ordinary_code() -> None:
    stop = _StopRequest()
    _signal_in("/somewhere/elastoflow/simulation/_simulation.py", stop)
    assert stop.requested
    with pytest.raises(KeyboardInterrupt):
        _signal_in("/somewhere/elastoflow/simulation/_simulation.py", stop)


@pytest.mark.parametrize("where", ["/venv/lib/python3.11/site-packages/numba/core/caching.py",
                                   "/venv/lib/python3.11/site-packages/llvmlite/binding/ffi.py"])
def test_inside_the_compiler_the_second_ctrl_c_waits_for_the_step(where: str) -> None:
    stop = _StopRequest()
    _signal_in(where, stop)
    _signal_in(where, stop)  # no KeyboardInterrupt inside the compiler
    assert stop.requested


def test_after_the_stepping_a_ctrl_c_does_not_cut_the_outputs_short() -> None:
    """Once the stepping ends, the outputs are closed and the resume command printed; a
    second Ctrl-C landing there (2 ms after the first, on a fast step) used to exit 130
    without the command. The handler stays until `release`, which gives Ctrl-C back."""
    previous = signal.getsignal(signal.SIGINT)
    stop = _StopRequest()
    try:
        with stop:
            _signal_in("/somewhere/elastoflow/cli.py", stop)
        assert signal.getsignal(signal.SIGINT) == stop._handle
        _signal_in("/somewhere/elastoflow/cli.py", stop)  # no KeyboardInterrupt
        assert stop.requested
    finally:
        stop.release()
    assert signal.getsignal(signal.SIGINT) == previous
    stop.release()  # a second release changes nothing
    assert signal.getsignal(signal.SIGINT) == previous


class _RaisesInDel:
    """Runs the second Ctrl-C's handler inside ``__del__``, where Python cannot raise."""

    def __init__(self, stop: _StopRequest) -> None:
        self.stop = stop

    def __del__(self) -> None:
        _signal_in("/somewhere/elastoflow/simulation/_simulation.py", self.stop)


def test_a_second_ctrl_c_landing_in_a_finalizer_is_raised_after_it(
        capsys: pytest.CaptureFixture[str]) -> None:
    """CI saw the second Ctrl-C land in a weakref callback run by the garbage collector:
    Python printed 'Exception ignored in ...' with a traceback and swallowed the interrupt.
    It is now delivered again and raised at the next point that can raise it."""
    previous_hook = sys.unraisablehook
    stop = _StopRequest()
    raised_after = False
    try:
        with stop:
            stop.requested = True
            try:
                victim = _RaisesInDel(stop)
                del victim
                deadline = time.monotonic() + 5.0
                while time.monotonic() < deadline:  # delivered again within milliseconds
                    time.sleep(0.001)
            except KeyboardInterrupt:
                raised_after = True
    finally:
        stop.release()
    assert raised_after
    assert "Exception ignored" not in capsys.readouterr().err
    assert sys.unraisablehook is previous_hook


def test_other_unraisable_exceptions_still_reach_the_previous_hook() -> None:
    seen: list[type[BaseException]] = []
    previous_hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: seen.append(unraisable.exc_type)
    stop = _StopRequest()
    try:
        with stop:
            class Broken:
                def __del__(self) -> None:
                    raise ValueError("in a finalizer")

            victim = Broken()
            del victim
    finally:
        stop.release()
        sys.unraisablehook = previous_hook
    assert seen == [ValueError]
