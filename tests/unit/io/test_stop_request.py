"""The second Ctrl-C of ``elastoflow run`` stops at once, except inside Numba's compiler or
cache loader: an exception raised there lands in an llvmlite ctypes callback and the process
died of SIGSEGV (a double Ctrl-C during the first step, seen in the fault tests)."""

from __future__ import annotations

import signal
import sys

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
