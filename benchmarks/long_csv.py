"""Memory and time of ``verticality estimate`` on a long IMU CSV: writes a synthetic recording
of ``--rows`` rows (default 10⁷, 1 kHz, a sensor swinging about two axes; ~600 MB) to a temporary
folder, runs the command in a child process, and prints the file size, the wall time and the
child's peak resident memory (``ru_maxrss``), and their ratio to the file size.

``python benchmarks/long_csv.py [--rows N] [--also SRC ...]``: ``--also`` runs the command of
another source tree (its ``src`` folder, e.g. an older checkout) on the same file, after ours."""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_csv(path: Path, rows: int, chunk: int = 1_000_000) -> None:
    rng = np.random.default_rng(0)
    with path.open("w") as f:
        f.write("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n")
        for k0 in range(0, rows, chunk):
            t = np.arange(k0, min(rows, k0 + chunk)) * 1e-3
            roll, pitch = 0.4 * np.sin(0.7 * t), 0.3 * np.sin(0.45 * t + 1.0)
            gyr = np.column_stack([0.28 * np.cos(0.7 * t), 0.135 * np.cos(0.45 * t + 1.0),
                                   np.zeros_like(t)]) + rng.normal(0, 2e-3, (t.size, 3))
            acc = 9.81 * np.column_stack([-np.sin(pitch), np.sin(roll) * np.cos(pitch),
                                          np.cos(roll) * np.cos(pitch)])
            acc += rng.normal(0, 0.03, acc.shape)
            np.savetxt(f, np.column_stack([t, gyr, acc]), fmt="%.6f", delimiter=",")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=10_000_000)
    ap.add_argument("--also", nargs="*", default=[], metavar="SRC")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        src, out = Path(tmp) / "long.csv", Path(tmp) / "tilt.csv"
        write_csv(src, args.rows)
        size = src.stat().st_size
        for tree in [None, *args.also]:
            env = dict(os.environ)
            if tree is not None:
                env["PYTHONPATH"] = str(Path(tree).resolve())
            t0 = time.perf_counter()
            proc = subprocess.Popen([sys.executable, "-m", "verticality", "estimate", str(src),
                                     "--out", str(out)], stdout=subprocess.DEVNULL, env=env)
            _, status, usage = os.wait4(proc.pid, 0)
            wall = time.perf_counter() - t0
            rss = usage.ru_maxrss * 1024
            print(f"{tree or 'this tree'}: {args.rows} rows, {size / 1e6:.0f} MB: exit "
                  f"{os.waitstatus_to_exitcode(status)}, {wall:.1f} s, peak RSS "
                  f"{rss / 1e9:.2f} GB ({rss / size:.1f}× the file)", flush=True)

if __name__ == "__main__":
    main()
