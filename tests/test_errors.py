"""Input errors (turbinefit.errors): one line naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from turbinefit.errors import InputError
from turbinefit.io import read_tum


def test_input_error_is_one_line_with_path(tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("1 2 3\n")
    with pytest.raises(InputError) as info:
        read_tum(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}:1: ")
    assert info.value.path == path


def test_an_interrupt_wrapped_by_a_library_is_found() -> None:
    import ctypes
    import signal

    from turbinefit.errors import Interrupted, interrupt_within

    term = Interrupted(signal.SIGTERM)
    try:  # pybind11's module initialisation: ImportError with the interrupt as its cause
        raise ImportError("initialization failed") from term
    except ImportError as e:
        assert interrupt_within(e) is term
    # ctypes keeps only the name: the last interrupt raised of that name
    assert interrupt_within(ctypes.ArgumentError("argument 3: Interrupted: SIGTERM")) is term
    found = interrupt_within(ctypes.ArgumentError("argument 1: Interrupted: SIGHUP"))
    assert isinstance(found, Interrupted) and found.signum == signal.SIGHUP
    plain = interrupt_within(ctypes.ArgumentError("argument 2: KeyboardInterrupt: "))
    assert type(plain) is KeyboardInterrupt
    assert interrupt_within(ImportError("no module named onnx")) is None
    assert interrupt_within(ctypes.ArgumentError("argument 2: TypeError: wrong type")) is None


def test_a_signal_while_ctypes_converts_a_kernels_arguments_is_the_signal() -> None:
    # numpy's ndpointer checks run Python code, where a signal's handler raises: ctypes
    # would report "ArgumentError: argument N: Interrupted: SIGINT" (a traceback)
    import ctypes
    import signal

    from turbinefit import _native
    from turbinefit.errors import Interrupted

    class Interrupting:
        @classmethod
        def from_param(cls, obj: object) -> object:
            raise Interrupted(signal.SIGINT)

    kernel = ctypes.CDLL(None).labs
    kernel.argtypes = [Interrupting]
    with pytest.raises(Interrupted) as caught:
        _native._run(kernel, 1)
    assert caught.value.signum == signal.SIGINT
    kernel.argtypes = [ctypes.c_long]
    assert _native._run(kernel, -3) == 3
    with pytest.raises(ctypes.ArgumentError):  # any other conversion error stays itself
        _native._run(kernel, "x")
