"""The figure scripts run from a fresh install and write their PNGs (at reduced size)."""
import os
import subprocess
import sys

import imageio.v3 as iio
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_paper_modes_script_writes_every_mode(tmp_path):
    out = tmp_path / "modes"
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "paper_modes.py"), "-o", str(out),
                           "--pings", "3", "--max-range", "30"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    names = ["speckle_free", "lfm_baseband", "lfm_carrier", "cw_incoherent", "cw_coherent",
             "cw_incoherent_histogram", "modes"]
    assert sorted(os.listdir(out)) == sorted(f"{n}.png" for n in names)
    free = iio.imread(out / "speckle_free.png")
    speckled = iio.imread(out / "cw_coherent.png")
    assert free.shape == speckled.shape and free.shape[0] == 3
    # speckle makes neighbouring pixels differ far more than the smooth expected intensity
    assert np.std(np.diff(speckled.astype(float), axis=1)) > 3 * np.std(np.diff(free.astype(float), axis=1))
