"""The servo log on the mocap clock: the offset between two PCs' clocks, from one motion seen by both.

The mocap PC and the servo PC keep their own clocks. A motion both record (a segment's bend rate from
the tracked bodies, the matching tendon's tick rate from the servo log) is resampled onto one uniform
grid, standardised, and cross-correlated; the shift s with the highest correlation is the offset,
such that `t_servo + s` is the mocap-clock time of each servo sample.

What the offset absorbs: any delay between the two signals that is physics rather than clocks. A
servo's measured position (present ticks) and the mocap see the same shaft move, so their delay is
the clocks' alone (plus the servo's read latency); a commanded signal (goal ticks) leads the motion
by the rig's response time, and an offset fitted against it carries that lag. Fit against what the
servo measured when the log has it.

Refused (CaptureError, "<source>: <what> (rule: <rule>)"): too little overlap between the two signals within the
searched shifts, a flat correlation (peak below `min_peak_correlation`: no shared motion, or a signal
that does not vary), two peaks (a second peak, outside the first's lobe, within
`max_second_peak_ratio` of the first: a periodic motion, whose shift is known only modulo its
period), and a peak at the edge of the searched window (the best shift may lie outside it).
`check_drift` refuses a clock drift past a limit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.signal import correlate, correlation_lags

from .errors import CaptureError

# a window of one signal whose variance is below this fraction of the signal's own does not vary
# there: its correlation is taken as 0, not as whatever rounding makes of 0 / 0
FLAT_VARIANCE = 1e-6


@dataclass(frozen=True)
class ClockFit:
    offset_s: float  # t_servo + offset_s is the mocap-clock time of a servo sample
    uncertainty_s: float  # see estimate_offset
    peak_correlation: float  # Pearson r at the refined peak
    second_peak_ratio: float  # highest other peak / the peak, 0 when there is none
    method: str
    n_samples: int  # grid samples paired at the peak
    dt_s: float  # the common grid's step

    def to_meta(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class ClockDrift:
    rate: float  # d(offset)/d(t_servo), seconds per second: 1e-6 is 1 ppm
    uncertainty: float  # same unit, from the two fits' uncertainties
    first: ClockFit
    last: ClockFit
    t_first: float  # servo-clock centres of the two windows
    t_last: float

    @property
    def ppm(self) -> float:
        return self.rate * 1e6

    def to_meta(self) -> dict:
        return dict(
            drift=self.rate,
            drift_uncertainty=self.uncertainty,
            t_servo_first=self.t_first,
            t_servo_last=self.t_last,
            first=self.first.to_meta(),
            last=self.last.to_meta(),
        )


@dataclass(frozen=True)
class ClockFitOptions:
    """How estimate_offset searches for the shift, when it refuses one, and what it calls the signals."""

    max_shift_s: float  # the shifts searched: guess_s +- max_shift_s
    guess_s: float = 0.0  # the centre of the searched shifts
    dt: float | None = None  # the common grid's step; None: the finer of the two sampling steps
    max_gap_s: float = 0.1  # a NaN gap longer than this stays NaN rather than being bridged
    min_overlap_s: float = 5.0  # the least shared time at a shift for its correlation to count
    min_peak_correlation: float = 0.5  # a lower peak is a flat correlation
    max_second_peak_ratio: float = 0.8  # a second peak this close to the first makes the shift ambiguous
    lobe_fraction: float = 0.5  # the peak's lobe: the shifts around it where r >= lobe_fraction * peak
    batches: int = 20  # batch means for the standard error of the correlation's slope
    motion_name: str = "motion"  # the mocap signal, as messages and the fit's method name it
    command_name: str = "command"  # the servo signal, likewise


def estimate_offset(t_mocap, motion, t_servo, command, options: ClockFitOptions, source="clock") -> ClockFit:
    """The shift s in guess_s +- max_shift_s maximising the correlation of motion(t) and command(t - s).

    The settings named here are the fields of `options`. Both signals are linearly interpolated
    onto grids of one step, `dt` or the finer of the two sampling steps; a NaN gap longer than
    `max_gap_s` stays NaN rather than being bridged. At each shift the correlation is the Pearson r
    of the grid samples both signals have there (at least `min_overlap_s` of them), so gaps and the
    ends of the take weigh nothing. The best grid shift is refined by a parabola through it and its
    two neighbours. The peak's lobe is the run of shifts around it where r >= lobe_fraction * peak;
    a second peak is the highest local maximum outside it.

    Uncertainty: the standard error of the peak's position from the noise in the data. The peak is
    where the correlation's slope r'(s) crosses zero; an error e in that slope moves the crossing
    by e / k, k = -r''(s) the peak's curvature (from the parabola). The slope's standard error comes
    from batch means (see _slope_error): the overlap cut into `batches` contiguous pieces, the
    spread of their slopes over sqrt(batches). Noise adds to the slope's scatter and lowers the
    peak's curvature, so the uncertainty grows with it. It is statistical only: the parabola's own
    bias and any physical delay between the signals (see the module's docstring) are not in it.
    On 40 synthetic noisy takes it covered 62 % of the errors, twice it 92 % (tests).
    """
    steps = _step(source, t_mocap, motion), _step(source, t_servo, command)
    dt = options.dt or min(steps)
    max_gap_s, min_overlap_s = options.max_gap_s, options.min_overlap_s
    guess_s, max_shift_s = options.guess_s, options.max_shift_s
    motion_name, command_name = options.motion_name, options.command_name
    t_mocap, t_servo = np.asarray(t_mocap, float), np.asarray(t_servo, float)
    # each signal on its own grid, both with step dt: grid shift k (mocap index - servo index) is
    # the clock shift gm0 - gs0 + k dt
    grid_mocap = t_mocap[0] + dt * np.arange(int((t_mocap[-1] - t_mocap[0]) / dt) + 1)
    grid_servo = t_servo[0] + dt * np.arange(int((t_servo[-1] - t_servo[0]) / dt) + 1)
    x = _standardise(_resample(t_mocap, motion, grid_mocap, max_gap_s))
    y = _standardise(_resample(t_servo, command, grid_servo, max_gap_s))
    r, n_pairs = _pearson_by_lag(x, y)
    lags = correlation_lags(len(x), len(y))
    shift = grid_mocap[0] - grid_servo[0] + dt * lags
    inside = np.abs(shift - guess_s) <= max_shift_s
    r, n_pairs, shift, lags = r[inside], n_pairs[inside], shift[inside], lags[inside]

    enough = n_pairs * dt >= min_overlap_s
    if not enough.any():
        raise CaptureError(
            source, f"too little overlap: under {min_overlap_s:g} s of {motion_name} and {command_name} "
            f"share the mocap clock at any shift within {guess_s:g} +- {max_shift_s:g} s",
            f"at least {min_overlap_s:g} s of shared motion",
        )
    r = np.where(enough, r, np.nan)
    best = int(np.argmax(np.where(np.isfinite(r), r, -np.inf)))
    peak = r[best]
    if not peak >= options.min_peak_correlation:
        raise CaptureError(
            source, f"flat correlation: {motion_name} and {command_name} correlate at most {peak:.2f} "
            f"(minimum {options.min_peak_correlation:g}), no shared motion to align on",
            "a clock shift is found from one clear correlation peak",
        )
    lo, hi = _lobe(r, best, options.lobe_fraction * peak)
    ratio = max(_second_peak(r, lo, hi), 0.0) / peak
    if ratio >= options.max_second_peak_ratio:
        raise CaptureError(
            source, f"two peaks: the correlation of {motion_name} and {command_name} has a second peak "
            f"{ratio:.2f} of the first (limit {options.max_second_peak_ratio:g}), the shift is ambiguous",
            "a clock shift is found from one clear correlation peak",
        )
    if best == 0 or best == len(r) - 1 or not np.isfinite(r[best - 1] + r[best + 1]):
        raise CaptureError(
            source, f"the correlation of {motion_name} and {command_name} peaks at the edge of the "
            f"searched shifts ({shift[best]:.3f} s): the best shift may lie outside {guess_s:.3f} +- {max_shift_s:g} s",
            "a clock shift is found from one clear correlation peak",
        )

    r_before, r_best, r_after = r[best - 1], r[best], r[best + 1]
    curv = r_before - 2 * r_best + r_after  # < 0 at a maximum
    delta = 0.5 * (r_before - r_after) / curv if curv < 0 else 0.0
    r_peak = r_best - 0.25 * (r_before - r_after) * delta
    se = _slope_error(x, y, int(lags[best]), dt, options.batches) / max(-curv / dt**2, 1e-12)
    return ClockFit(
        offset_s=float(shift[best] + delta * dt),
        uncertainty_s=float(se),
        peak_correlation=float(r_peak),
        second_peak_ratio=float(ratio),
        method=f"cross-correlation of {motion_name} (mocap) and {command_name} (servo)",
        n_samples=int(n_pairs[best]),
        dt_s=float(dt),
    )


def measure_drift(t_mocap, motion, t_servo, command, options: ClockFitOptions, *, part: float = 1 / 3,
                  source="clock") -> ClockDrift:
    """The offset in the first and the last `part` of the overlap, and its rate of change.

    The whole-take fit first gives the overlap on the servo clock; each window is then fitted around
    that offset (options as estimate_offset's, guess_s the whole take's offset). rate = (last - first)
    / (distance of the windows' centres), its uncertainty the two fits' uncertainties added in
    quadrature over that distance."""
    t_servo = np.asarray(t_servo, float)
    command = np.asarray(command, float)
    whole = estimate_offset(t_mocap, motion, t_servo, command, options, source)
    start = max(t_servo[0], np.asarray(t_mocap, float)[0] - whole.offset_s)
    end = min(t_servo[-1], np.asarray(t_mocap, float)[-1] - whole.offset_s)
    width = part * (end - start)
    around = replace(options, guess_s=whole.offset_s)
    fits = []
    for window_start in (start, end - width):
        inside = (t_servo >= window_start) & (t_servo <= window_start + width)
        fits.append(estimate_offset(t_mocap, motion, t_servo[inside], command[inside], around, source))
    span = end - width - start
    return ClockDrift(
        rate=(fits[1].offset_s - fits[0].offset_s) / span,
        uncertainty=float(np.hypot(fits[0].uncertainty_s, fits[1].uncertainty_s) / span),
        first=fits[0],
        last=fits[1],
        t_first=float(start + width / 2),
        t_last=float(end - width / 2),
    )


def check_drift(drift: float, limit: float, source="clock") -> None:
    """Refuse a drift (seconds per second) whose size exceeds limit: one offset would misplace the
    servo samples at the ends of the take by more than the importer accepts."""
    if not abs(drift) <= limit:
        raise CaptureError(source, f"clock drift {drift * 1e6:.1f} ppm", f"clock drift <= {limit * 1e6:g} ppm")


def _step(source, t, x):
    t, x = np.asarray(t, float), np.asarray(x, float)
    if t.shape != x.shape or t.ndim != 1 or len(t) < 2:
        raise CaptureError(
            source,
            "times and values are not 1-D arrays of one length",
            "at least two samples of a signal",
        )
    if not (np.diff(t) > 0).all():
        raise CaptureError(
            source,
            "timestamps do not increase",
            "timestamps increase",
        )  # np.interp needs them increasing
    return float(np.median(np.diff(t)))


def _resample(t, x, grid, max_gap_s):
    """x at the grid times, linearly interpolated between valid samples at most max_gap_s apart."""
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    tv, xv = t[ok], x[ok]
    if len(tv) < 2:
        return np.full(len(grid), np.nan)
    y = np.interp(grid, tv, xv, left=np.nan, right=np.nan)
    j = np.clip(np.searchsorted(tv, grid), 1, len(tv) - 1)  # tv[j - 1] <= grid <= tv[j]
    y[tv[j] - tv[j - 1] > max_gap_s] = np.nan
    return y


def _standardise(x):
    """Zero mean, unit variance over the valid samples; a signal that does not vary becomes 0."""
    mean, std = np.nanmean(x), np.nanstd(x)
    if not std > 1e-12 * abs(mean):  # a constant, up to the rounding of its mean
        return np.where(np.isfinite(x), 0.0, np.nan)
    return (x - mean) / std


def _pearson_by_lag(x, y):
    """Pearson r of x[i] and y[i - k] over the pairs both have, for every lag k, and their count.

    Six correlations of the zero-filled signals and their masks give each lag's sums: the usual
    normalised cross-correlation would instead divide by the whole signals' norms, which misweighs
    the lags where gaps or the ends of the take leave only part of them overlapping."""
    mx, my = np.isfinite(x).astype(float), np.isfinite(y).astype(float)
    x0, y0 = np.nan_to_num(x), np.nan_to_num(y)
    n = np.rint(correlate(mx, my))
    sx, sy = correlate(x0, my), correlate(mx, y0)
    with np.errstate(invalid="ignore", divide="ignore"):
        vx = correlate(x0**2, my) - sx**2 / n
        vy = correlate(mx, y0**2) - sy**2 / n
        r = (correlate(x0, y0) - sx * sy / n) / np.sqrt(vx * vy)
        flat = (vx < FLAT_VARIANCE * n) | (vy < FLAT_VARIANCE * n)
    return np.where(n > 0, np.where(flat, 0.0, r), np.nan), n


def _slope_error(x, y, lag, dt, batches):
    """Standard error of the correlation's slope at a lag (pairs x[m], y[m - lag]), by batch means.

    The slope of mean(x(t) y(t - s)) in s is mean(x' y) = -mean(x y') up to the record's ends; their
    average (x' y - x y') / 2 is used because a signal's part shared with the other cancels in it
    term by term, where x y' alone would carry d(y^2)/dt / 2, which sums to nothing over the take but
    scatters the batches. The terms are correlated over the signals' correlation time, so the means
    of contiguous batches, each much longer than that, stand in for independent samples: their
    spread over sqrt(batches) is the standard error."""
    m = np.arange(max(1, lag + 1), min(len(x) - 1, len(y) + lag - 1))
    j = m - lag
    q = ((x[m + 1] - x[m - 1]) * y[j] - x[m] * (y[j + 1] - y[j - 1])) / (4 * dt)
    means = [b.mean() for b in np.array_split(q[np.isfinite(q)], batches) if len(b)]
    return float(np.std(means, ddof=1) / np.sqrt(len(means))) if len(means) > 1 else np.inf


def _lobe(r, i, floor):
    """The run of lags around i where r stays at or above floor: the peak's lobe."""
    lo, hi = i, i
    while lo > 0 and r[lo - 1] >= floor:
        lo -= 1
    while hi < len(r) - 1 and r[hi + 1] >= floor:
        hi += 1
    return lo, hi


def _second_peak(r, lo, hi):
    """The highest local maximum of r outside the lobe lo..hi; the window's ends count (a peak may
    sit just beyond them). 0 when there is none."""
    q = np.where(np.isfinite(r), r, -np.inf)
    left, right = np.r_[-np.inf, q[:-1]], np.r_[q[1:], -np.inf]
    is_max = (q >= left) & (q >= right) & np.isfinite(q)
    is_max[lo : hi + 1] = False
    return float(q[is_max].max()) if is_max.any() else 0.0
