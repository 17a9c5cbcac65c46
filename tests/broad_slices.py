"""The BROAD slices shipped with the tests (tests/data/broad/README.md: what they hold, their
licence, and the script that cuts them)."""

from pathlib import Path

DIR = Path(__file__).resolve().parent / "data" / "broad"
SLOW_ROTATION = DIR / "01_undisturbed_slow_rotation_A.hdf5"  # samples 0–14 000 of the trial
FAST_ROTATION = DIR / "06_undisturbed_fast_rotation_A.hdf5"  # samples 20 000–21 600
FAST_TRANSLATION = DIR / "15_undisturbed_fast_translation_A.hdf5"  # samples 0–24 572
ALL = (SLOW_ROTATION, FAST_ROTATION, FAST_TRANSLATION)
