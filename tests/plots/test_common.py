"""Plot helpers (turbinefit.plots.common), and matplotlib imported only when plotting."""

from __future__ import annotations

import subprocess
import sys

from turbinefit.plots import choose_keyframes


def test_importing_turbinefit_does_not_import_matplotlib():
    code = "import sys, turbinefit, turbinefit.plots; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_choose_keyframes():
    assert choose_keyframes(100, 6) == [0, 20, 40, 59, 79, 99]
    assert choose_keyframes(4, 6) == [0, 1, 2, 3]
    assert choose_keyframes(0) == []
    assert choose_keyframes(10, 0) == []
    assert choose_keyframes(9, 1) == [4]
    k = choose_keyframes(7, 6)
    assert len(k) == len(set(k)) == 6 and k[0] == 0 and k[-1] == 6
