"""Cut the BROAD slices the tests read from a folder of the BROAD trials (HDF5).

Run: ``python tests/data/broad/cut.py BROAD_DIR`` (BROAD_DIR holds the trials' .hdf5 files, as
published by the dataset's authors). Each slice keeps the datasets the readers of
``verticality.io.broad`` use (``imu_gyr``, ``imu_acc``, ``opt_quat``, ``movement``; not the
magnetometer nor the optical position), bit for bit, with the ``sampling_rate`` and ``info``
attributes and a ``slice`` attribute naming the samples kept. The tests assume these samples:
change a range here and re-derive what they assert on it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import h5py

HERE = Path(__file__).resolve().parent
KEYS = ("imu_gyr", "imu_acc", "opt_quat", "movement")
# trial -> (first sample, end sample); at 285.714 Hz
SLICES = {
    # 49 s: rest, then slow rotations up to 3 rad/s (from the start, so that t is the trial's)
    "01_undisturbed_slow_rotation_A": (0, 14_000),
    # 5.6 s of fast rotation from sample 20 000 (70 s into the trial)
    "06_undisturbed_fast_rotation_A": (20_000, 21_600),
    # 86 s from the start: rest, fast translations, and the optical dropout at 84.2 s
    "15_undisturbed_fast_translation_A": (0, 24_572),
}


def cut(broad_dir: Path, out_dir: Path = HERE) -> list[Path]:
    written = []
    for name, (a, b) in SLICES.items():
        src = broad_dir / f"{name}.hdf5"
        if not src.is_file():
            raise SystemExit(f"{src}: no such BROAD trial")
        dst = out_dir / f"{name}.hdf5"
        with h5py.File(src, "r") as f, h5py.File(dst, "w", track_order=True) as g:
            for key in KEYS:
                g.create_dataset(key, data=f[key][a:b], compression="gzip", compression_opts=9,
                                 shuffle=True)
            g.attrs["sampling_rate"] = f.attrs["sampling_rate"]
            g.attrs["info"] = f.attrs.get("info", "")
            g.attrs["slice"] = f"samples {a}:{b} of {name} (BROAD)"
        written.append(dst)
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("broad_dir", type=Path, metavar="BROAD_DIR",
                    help="folder of BROAD .hdf5 trials")
    args = ap.parse_args(argv)
    for path in cut(args.broad_dir):
        print(f"{path.name}: {path.stat().st_size / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
