"""How the tilt filter reads time: each sample's step from its time stamp and, where the stamps
step by more than a gap, from its readings (docs/tilt.md, "Gaps and clock jumps").

A step of the stamps longer than a gap (``gap_flag_s``) is one of two things, and the readings
across it tell which. A **gap**: time passed and samples were lost, so the readings after it
differ from those before by what the motion did meanwhile. A **clock jump**: the logger's clock
was set (forward or back) while the sensor went on sampling, so the readings after it continue
those before as from one sample to the next. The evidence is the residual of each reading after
a straight line through the two readings before it, ``e_k = x_k − 2 x_{k−1} + x_{k−2}`` (gyro
and accelerometer apart): across one sample it is the sensor's noise and the motion's curvature
over one step, across a gap of T s the motion's change over T. A step is a clock jump when both
residuals are within :data:`CONTINUITY` times the recent ones (the lower median of the last
:data:`WINDOW` residuals between regular steps, at least a floor of a few converter steps):
measured on the validation's hand-held motions at 50–1000 Hz, a regular sample's residual is at
most 4.2 times that median, a dropout's at least 8 times (the accelerometer's) and 28 times (the
gyro's). A gap the readings cannot tell from one sample (at rest, or a motion that came back to
where it was) is one across which the tilt did not change beyond what the test lets through:
taking it as one sample is then safe too.

A clock jump is taken as one sample at the nominal step (the lower median of the last regular
steps; no rotation is invented over the jumped time), flagged ``CLOCK_JUMP``, and not re-acquired:
the readings show that no motion was missed, so the tilt and its covariance carry over. Its σ is
widened by the tilt change the test lets through (the accepted accelerometer residual over g,
taken as 2σ). A gap is as before: the step as the stamps say, flagged ``DT_GAP`` by the filter,
the tilt re-acquired after ``reacquire_s``.

The stamps (as :func:`verticality.tilt.output.time_axis` and the readers give them, steps from
the previous stamp) are followed as ``verticality stream`` always has: a step that goes forward
by less than ``MAX_DT_S`` is taken from the last time taken; a stamp that does not (back by more
than a gap, or absurdly far ahead) is a clock jump when the readings go on (the sample taken at
the nominal step, the clock not yet followed), else its sample is skipped (``BAD_DT``); when the
next stamp goes on from it, the clock was set and is followed from there (after a skipped sample,
a set clock is a break: the step is at least :func:`break_step_s`, a gap). A step back by less
than a gap, or of zero, skips its sample as before.

One rule for every reader of time: :class:`Clock` judges sample by sample (:class:`verticality.
tilt.Stream`, ``verticality stream``), :meth:`Clock.steps` a piece of a recording at once, the
same numbers (``tilt.estimate``, ``tilt.smooth``, ``verticality estimate``), and
:func:`judge_steps` a whole recording. Causal: a sample's step is judged from its own readings
and the past only.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

from verticality.tilt.flags import CLOCK_JUMP
from verticality.tilt.params import (
    DEFAULT_PARAMS,
    GAP_TOLERANCE_S,
    MAX_ACC_M_S2,
    MAX_DT_S,
    MAX_RATE_RAD_S,
    TiltParams,
)

WINDOW = 31  # the recent residuals (and regular steps) a step is judged against
MIN_WINDOW = 8  # fewer recent residuals: no evidence, the step is what the stamps say
CONTINUITY = 5.0  # a clock jump's residuals are at most this many times the recent median
# floors of the recent residual (a quiet sensor read by a converter repeats its codes, and its
# residuals are zero): a few steps of common MEMS converters (a ±2000 °/s gyro's 16-bit step is
# 1.1e-3 rad/s, a ±16 g accelerometer's 4.8e-3 m/s²)
GYR_FLOOR_RAD_S = 2e-3
ACC_FLOOR_M_S2 = 1e-2

NORMAL, JUMP, GAP, SKIP = 0, 1, 2, 3  # how a sample's step was taken (Clock.kind)


def break_step_s(params: TiltParams = DEFAULT_PARAMS) -> float:
    """The step given across a break in the clock (a set clock after a skipped sample): the
    shortest that the filter takes as a gap (``gap_flag_s`` and its rounding tolerance), so that
    what it integrates over the unknown time stays the least a gap allows."""
    return params.gap_flag_s + 2 * GAP_TOLERANCE_S


def _lower_median(values) -> float:
    """The lower median of a non-empty sequence (an element of it: no arithmetic, so that the
    sample-by-sample and the batch forms agree bit for bit)."""
    s = sorted(values)
    return s[(len(s) - 1) // 2]


class Judged(NamedTuple):
    """The steps of a recording as the filter takes them (:func:`judge_steps`)."""

    dt_s: np.ndarray  # (N,) the step of each sample (NaN: skipped)
    tilt_var_rad2: np.ndarray  # (N,) the tilt variance a clock jump adds
    flags: np.ndarray  # (N,) int32: CLOCK_JUMP
    kind: np.ndarray  # (N,) int8: NORMAL, JUMP, GAP, SKIP


class Clock:
    """The time of a stream of samples as the tilt filter takes it (module doc)::

        c = Clock(params)
        c.first(gyr, acc)                               # the first sample (its step is given)
        dt, var, flags, kind = c.step(d_s, gyr, acc)    # d_s: its stamp minus the previous one
        judged = c.steps(d_s, gyr, acc)                 # or a piece at once: the same numbers

    ``var`` is the tilt variance (rad²) the sample adds and ``flags`` its flag bits
    (``CLOCK_JUMP``); ``kind`` one of ``NORMAL``, ``JUMP``, ``GAP``, ``SKIP``."""

    def __init__(self, params: TiltParams = DEFAULT_PARAMS):
        self.params = params
        self.gap_s = params.gap_flag_s + GAP_TOLERANCE_S
        self.break_s = break_step_s(params)
        self.started = False
        self.ahead = 0.0  # the previous stamp minus the last time taken
        self.behind = 0  # samples in a row whose stamp was not followed
        self.skipped = False  # one of them was skipped
        self.kind = NORMAL  # how the previous sample was taken
        self.d_last = math.nan  # the previous sample's step from its previous stamp
        self.x1 = self.x2 = None  # the readings of the previous two samples (None: not usable)
        self.eg2 = deque(maxlen=WINDOW)  # recent squared residuals, gyro and accelerometer
        self.ea2 = deque(maxlen=WINDOW)
        self.regular = deque(maxlen=WINDOW)  # recent regular steps

    # --- the evidence ---

    def _regular(self, d) -> bool:
        return 0.0 < d <= self.gap_s

    def _evidence(self, eg2, ea2, win_g, win_a, win_d):
        """``(jump, nominal step, tilt variance)`` for a step whose residuals are ``eg2``,
        ``ea2`` (squared; None: not all three readings usable) given the recent windows."""
        if eg2 is None or len(win_g) < MIN_WINDOW or self.kind not in (NORMAL, JUMP):
            return False, math.nan, 0.0  # (after a gap or a skipped sample: no evidence)
        c2 = CONTINUITY * CONTINUITY
        bound_g2 = c2 * max(_lower_median(win_g), GYR_FLOOR_RAD_S**2)
        bound_a2 = c2 * max(_lower_median(win_a), ACC_FLOOR_M_S2**2)
        if eg2 > bound_g2 or ea2 > bound_a2:
            return False, math.nan, 0.0
        g = self.params.g_m_s2
        return True, _lower_median(win_d), bound_a2 / (4.0 * g * g)

    # --- the rule ---

    def _judge(self, d, evidence):
        """``(kind, dt, tilt variance)`` of a sample whose step from the previous stamp is ``d``;
        ``evidence()`` the readings' verdict (:meth:`_evidence`), asked only for a step that
        may be a clock jump."""
        if not math.isfinite(d):  # no stamp: skipped, the clock where it was
            self.behind, self.skipped = self.behind + 1, True
            return SKIP, math.nan, 0.0
        s = self.ahead + d  # the step from the last time taken
        if 0.0 < s < MAX_DT_S:
            if s <= self.gap_s:
                kind, dt, var = NORMAL, s, 0.0
            else:
                jump, nominal, var = evidence()
                kind, dt, var = (JUMP, nominal, var) if jump else self._gap(s)
            self.ahead, self.behind, self.skipped = 0.0, 0, False
            return kind, dt, var
        if self.behind >= 1 and 0.0 < d < MAX_DT_S:  # the clock was set: followed from here
            if d > self.gap_s:  # a step beyond a gap on the new clock: nothing to compare with
                kind, dt, var = self._gap(d)
            elif self.skipped and (s >= MAX_DT_S or -s > self.gap_s):
                kind, dt, var = GAP, max(d, self.break_s), 0.0  # a break: re-acquired
            else:
                kind, dt, var = NORMAL, d, 0.0
            self.ahead, self.behind, self.skipped = 0.0, 0, False
            return kind, dt, var
        if s >= MAX_DT_S or -s > self.gap_s:  # far ahead, or back by more than a gap
            jump, nominal, var = evidence()
            if jump and abs(s) >= MAX_DT_S:  # an absurd stamp: followed (the next one that
                self.ahead, self.behind, self.skipped = 0.0, 0, False  # comes back is one too)
                return JUMP, nominal, var
            if jump:  # the readings go on: one sample, the stamp not yet followed
                self.ahead, self.behind = s - nominal, self.behind + 1
                return JUMP, nominal, var
        self.ahead, self.behind, self.skipped = s, self.behind + 1, True
        return SKIP, math.nan, 0.0

    def _gap(self, span_s):
        """``(GAP, step, tilt variance)`` of a gap of ``span_s`` s: the step as the stamps say
        (the filter flags it ``DT_GAP``, adds the unknown rotation over it and re-acquires the
        tilt), nothing added here."""
        return GAP, span_s, 0.0

    # --- sample by sample ---

    @staticmethod
    def _reading(gyr, acc):
        """The six readings as a tuple, or None when one is not finite or beyond the sensor's
        physical range (such a sample is no evidence)."""
        x = (float(gyr[0]), float(gyr[1]), float(gyr[2]), float(acc[0]), float(acc[1]),
             float(acc[2]))
        for i in range(6):
            if not abs(x[i]) < (MAX_RATE_RAD_S if i < 3 else MAX_ACC_M_S2):
                return None
        return x

    def _residuals(self, x):
        x1, x2 = self.x1, self.x2
        if x is None or x1 is None or x2 is None:
            return None, None
        e = [(x[i] - 2.0 * x1[i]) + x2[i] for i in range(6)]
        return e[0] * e[0] + e[1] * e[1] + e[2] * e[2], e[3] * e[3] + e[4] * e[4] + e[5] * e[5]

    def _record(self, x, d, kind, eg2, ea2):
        if eg2 is not None and self._regular(d) and self._regular(self.d_last):
            self.eg2.append(eg2)
            self.ea2.append(ea2)
        if self._regular(d):
            self.regular.append(d)
        self.x2, self.x1, self.d_last, self.kind = self.x1, x, d, kind

    def first(self, gyr, acc) -> None:
        """The first sample (its step is the caller's: it only initializes the filter)."""
        self.started = True
        self._record(self._reading(gyr, acc), math.nan, NORMAL, None, None)

    def follow(self, d, gyr, acc) -> None:
        """A sample taken at the step ``d`` without judging it (a stream's fixed period):
        the clock is followed from it."""
        x = self._reading(gyr, acc)
        eg2, ea2 = self._residuals(x)
        self.ahead, self.behind, self.skipped = 0.0, 0, False
        self._record(x, d, NORMAL, eg2, ea2)

    def step(self, d, gyr, acc) -> tuple[float, float, int, int]:
        """``(dt, tilt variance, flags, kind)`` of the next sample, ``d`` its stamp minus the
        previous sample's (NaN: none)."""
        x = self._reading(gyr, acc)
        eg2, ea2 = self._residuals(x)
        kind, dt, var = self._judge(
            d, lambda: self._evidence(eg2, ea2, self.eg2, self.ea2, self.regular))
        self._record(x, d, kind, eg2, ea2)
        return dt, var, CLOCK_JUMP if kind == JUMP else 0, kind

    # --- a piece at once ---

    def steps(self, d_s, gyr, acc) -> Judged:
        """:meth:`step` over a piece of a recording (``d_s`` (n,), ``gyr``, ``acc`` (n, 3)); the
        first sample of the recording (when the clock has not started) keeps its step, as
        :meth:`first`. The same numbers as :meth:`step` sample by sample; the rows whose stamps
        step regularly are taken at once."""
        d = np.asarray(d_s, dtype=np.float64)
        n = d.shape[0]
        dt, var = d.copy(), np.zeros(n)
        kinds = np.zeros(n, dtype=np.int8)
        if n == 0:
            return Judged(dt, var, np.zeros(0, dtype=np.int32), kinds)
        x = np.concatenate([np.asarray(gyr, dtype=np.float64),
                            np.asarray(acc, dtype=np.float64)], axis=1)
        with np.errstate(invalid="ignore"):
            ok = np.all(np.abs(x[:, :3]) < MAX_RATE_RAD_S, axis=1) \
                & np.all(np.abs(x[:, 3:]) < MAX_ACC_M_S2, axis=1)
        # the previous two samples before the piece, then the piece
        prev = [np.full(6, np.nan) if v is None else np.array(v) for v in (self.x2, self.x1)]
        xx = np.concatenate([np.stack(prev), x])
        okx = np.concatenate([[self.x2 is not None, self.x1 is not None], ok])
        # a corrupt reading (beyond any sensor's range) may overflow here; its rows are not
        # judged (has_e below)
        with np.errstate(over="ignore", invalid="ignore"):
            e = (xx[2:] - 2.0 * xx[1:-1]) + xx[:-2]
            eg2 = e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1] + e[:, 2] * e[:, 2]
            ea2 = e[:, 3] * e[:, 3] + e[:, 4] * e[:, 4] + e[:, 5] * e[:, 5]
        has_e = okx[2:] & okx[1:-1] & okx[:-2]
        dd = d.copy()
        start = 0
        if not self.started:  # the first sample: no step of its own
            dd[0] = math.nan
            start = 1
        d_prev = np.concatenate([[self.d_last], dd[:-1]])
        with np.errstate(invalid="ignore"):
            regular = (dd > 0.0) & (dd <= self.gap_s)
            regular_prev = (d_prev > 0.0) & (d_prev <= self.gap_s)
        in_window = has_e & regular & regular_prev
        idx_e = np.flatnonzero(in_window)
        idx_d = np.flatnonzero(regular)
        old = (list(self.eg2), list(self.ea2), list(self.regular))

        def window(k):
            pe = np.searchsorted(idx_e, k)
            pd = np.searchsorted(idx_d, k)
            we = idx_e[max(0, pe - WINDOW):pe]
            wd = idx_d[max(0, pd - WINDOW):pd]
            more_e, more_d = WINDOW - we.size, WINDOW - wd.size
            return ((old[0][len(old[0]) - more_e:] if more_e else []) + eg2[we].tolist(),
                    (old[1][len(old[1]) - more_e:] if more_e else []) + ea2[we].tolist(),
                    (old[2][len(old[2]) - more_d:] if more_d else []) + d[wd].tolist())

        # the rows to judge one by one: those whose step is not regular, and the rows after them
        # until the clock is followed again (in between, a regular step is taken as it is)
        todo = np.flatnonzero(~regular[start:]) + start
        clean = self.ahead == 0.0 and self.behind == 0
        if not clean and start < n:
            todo = np.union1d(todo, [start])
        kind_prev = self.kind
        k_last = start - 1  # the last row judged one by one
        i = 0
        while i < todo.size:
            k = int(todo[i])
            i += 1
            if k <= k_last:
                continue
            if k > k_last + 1 and k > start:
                kind_prev = kinds[k - 1]  # (NORMAL: a regular row in between)
            while True:
                self.kind, self.d_last = kind_prev, d_prev[k]
                g2 = float(eg2[k]) if has_e[k] else None
                a2 = float(ea2[k]) if has_e[k] else None
                kind, dt_k, var_k = self._judge(
                    float(d[k]), lambda k=k, g2=g2, a2=a2: self._evidence(g2, a2, *window(k)))
                kinds[k], dt[k], var[k] = kind, dt_k, var_k
                kind_prev, k_last = kind, k
                k += 1
                if k >= n or (self.ahead == 0.0 and self.behind == 0 and regular[k]):
                    break
        # the state after the piece, as the sample-by-sample form leaves it
        self.started = True
        self.kind = int(kinds[-1]) if n else self.kind
        self.d_last = float(dd[-1])
        tail_e, tail_d = idx_e[-WINDOW:], idx_d[-WINDOW:]
        for win, old_v, new in ((self.eg2, old[0], eg2[tail_e]), (self.ea2, old[1], ea2[tail_e]),
                                (self.regular, old[2], d[tail_d])):
            win.clear()
            win.extend(old_v[len(old_v) - (WINDOW - new.size):] if new.size < WINDOW else [])
            win.extend(new.tolist())
        self.x2 = tuple(xx[-2].tolist()) if okx[-2] else None
        self.x1 = tuple(xx[-1].tolist()) if okx[-1] else None
        return Judged(dt, var, np.where(kinds == JUMP, CLOCK_JUMP, 0).astype(np.int32), kinds)


def judge_steps(dt_s, gyr, acc, params: TiltParams = DEFAULT_PARAMS) -> Judged | None:
    """The steps of a whole recording as the filter takes them (:class:`Clock`; ``dt_s`` (N,):
    ``dt_s[k]`` the step from sample k−1's stamp, the first one the sample's own), or None when
    there is nothing to judge: a fixed period (``dt_s`` a scalar) or every step regular (then the
    steps are taken as they are, bit for bit)."""
    dt = np.asarray(dt_s, dtype=np.float64)
    if dt.ndim != 1 or dt.shape[0] < 2:
        return None
    with np.errstate(invalid="ignore"):
        if np.all((dt[1:] > 0.0) & (dt[1:] <= params.gap_flag_s + GAP_TOLERANCE_S)):
            return None
    return Clock(params).steps(dt, gyr, acc)
