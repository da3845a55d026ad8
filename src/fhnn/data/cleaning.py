"""Cleaning a table's tracks: a tracker's glitches (outliers) dropped, outages (gaps) split at."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from fhnn.data.derivatives import lagrange_residuals, noise_level
from fhnn.data.table import MIN_SAMPLES, Table, Trajectory, position_series
from fhnn.errors import ConfigError

#: ``--max-gap auto``: a track is split where an interval is longer than this many times its
#: median step. Training rolls RK4 one step per interval; on issue 14's tracks (``steady_vortex``
#: observed every 0.05 s) one step's position error is at most 8.0e-6 m over 10 steps' time
#: (0.5 s), 2.2e-4 m over 20 and 5.7e-3 m over 40, against 1 mm of noise
#: (``benchmarks/gap_steps.py``, ``docs/design/data/gap_steps.txt``).
GAP_STEPS = 10.0
#: ``--outliers``' default: a position more than this many noise levels from the cubic through its
#: two neighbours either side is a glitch and is dropped (:func:`drop_outliers`). Pure noise goes
#: past 8σ about once in 10^15 samples; issue 14's tracks (1 mm noise, 0.05 s steps) reach 4.2σ.
OUTLIER_SIGMAS = 8.0
#: Passes of :func:`drop_outliers` over a track at most (each drops the worst sample of every
#: cluster of flagged ones).
OUTLIER_PASSES = 20


def _positive_or_word(text: str, option: str, word: str, unit: str) -> float | None:
    """``word`` → ``None``; otherwise a number > 0 (``option``'s value, in ``unit``), or a
    :class:`~fhnn.errors.ConfigError` naming the option."""
    if text.strip().lower() == word:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise ConfigError(f"{option} must be {word} or a number of {unit} > 0, got {text!r}")
    return value


def parse_max_gap(text: str) -> float | None:
    """``"auto"`` → ``None``; otherwise a number of seconds > 0 (``inf``: never split)."""
    return _positive_or_word(text, "--max-gap", "auto", "seconds")


def parse_outliers(text: str) -> float | None:
    """``"off"`` → ``None``; otherwise a number of noise levels > 0."""
    return _positive_or_word(text, "--outliers", "off", "noise levels")


def _residual_sigmas(t: np.ndarray, pos: np.ndarray, noise: float) -> np.ndarray:
    """``(n − 4,)``: for each interior sample of a track (times ``t`` ``(n,)``, positions
    ``pos`` ``(n, 2)``), the length of its residual vector from the cubic through its two
    neighbours either side, in noise levels ``noise`` [m] (a length: the same in turned axes)."""
    return np.hypot(*(lagrange_residuals(t, pos[:, k]) for k in range(2))) / noise


def drop_outliers(
    pieces: list[Trajectory], noise: float, sigmas: float, where: list[tuple[str, float]] | None = None
) -> tuple[list[Trajectory], int, int]:
    """Drop the glitches of a tracker: samples whose position lies more than ``sigmas`` times the
    noise level ``noise`` [m] from the cubic through their two neighbours on either side
    (:func:`~fhnn.data.derivatives.lagrange_residuals`, the residual vector's length). A glitch also pulls its
    neighbours' residuals (by up to 2/3 of its own), and one among a track's first or last two
    samples shows only in its neighbours', so for each run of flagged samples within 4 of each
    other the sample dropped is the one (of the run and two either side) whose removal leaves the
    least sum of squared residuals around it (a sum, not the largest: with two glitches in a run
    the other one's residual would tie every candidate); passes repeat (at most
    :data:`OUTLIER_PASSES`) until no sample is flagged. Returns ``(pieces, samples dropped, pieces
    with a drop)``, and each dropped sample's ``(trajectory id, time [s])`` appended to ``where``;
    with ``noise`` 0 nothing can be judged and nothing is dropped."""
    if not noise > 0:
        return pieces, 0, 0
    out: list[Trajectory] = []
    dropped = touched = 0
    for tr in pieces:
        keep = np.ones(tr.t.size, dtype=bool)
        for _ in range(OUTLIER_PASSES):
            idx = np.flatnonzero(keep)
            if idx.size < 6:
                break
            t, pos = tr.t[idx], tr.pos[idx]
            flagged = np.flatnonzero(_residual_sigmas(t, pos, noise) > sigmas) + 2  # samples
            if flagged.size == 0:
                break
            for run in np.split(flagged, np.flatnonzero(np.diff(flagged) > 4) + 1):
                lo, hi = max(run[0] - 2, 0), min(run[-1] + 2, idx.size - 1)
                around = np.arange(max(lo - 4, 0), min(hi + 4, idx.size - 1) + 1)
                rests = [around[around != j] for j in range(lo, hi + 1)]
                left = [np.sum(_residual_sigmas(t[r], pos[r], noise) ** 2) for r in rests]
                keep[idx[lo + int(np.argmin(left))]] = False
        if keep.all():
            out.append(tr)
            continue
        dropped += int((~keep).sum())
        touched += 1
        if where is not None:
            where.extend((tr.traj_id, float(time)) for time in tr.t[~keep])
        out.append(tr.take(keep))
    return out, dropped, touched


def without_outliers(
    trajectories: list[Trajectory], sigmas: float | None, where: list[tuple[str, float]] | None = None
) -> tuple[list[Trajectory], float, int, int]:
    """:func:`drop_outliers` at the noise level the trajectories' own positions show (``sigmas``
    None: none dropped): ``(trajectories, noise level of what is kept [m], samples dropped,
    trajectories with a drop)``. What ``fhnn import`` does to a table and ``fhnn predict`` to a
    ``--history``. ``where``: as for :func:`drop_outliers`."""
    noise = noise_level(position_series(trajectories))
    if sigmas is None:
        return trajectories, noise, 0, 0
    kept, dropped, touched = drop_outliers(trajectories, noise, sigmas, where)
    if dropped:
        noise = noise_level(position_series(kept))
    return kept, noise, dropped, touched


def drop_table_outliers(table: Table, sigmas: float | None) -> tuple[Table, int]:
    """``table`` without its glitches (:func:`without_outliers`; ``sigmas`` None: unchanged) and
    how many positions went: what ``fhnn predict`` does to a ``--history`` before fitting start
    states to it."""
    if sigmas is None:
        return table, 0
    kept, _, dropped, _ = without_outliers(table.trajectories, sigmas)
    return dataclasses.replace(table, trajectories=kept), dropped


@dataclasses.dataclass(frozen=True)
class GapSplit:
    """A table's tracks after :func:`split_at_gaps`: the ``pieces``, the index of the track each
    came from (``track`` ``(P,)``), how many gaps were cut in how many tracks, and how many pieces
    (and rows) were dropped for having fewer than :data:`MIN_SAMPLES` samples."""

    pieces: list[Trajectory]
    track: np.ndarray
    gaps: int
    split_tracks: int
    short_pieces: int
    short_rows: int


def split_at_gaps(trajectories: list[Trajectory], max_gap: float | None) -> GapSplit:
    """Split each track where two consecutive samples are more than ``max_gap`` seconds apart
    (``None``: more than :data:`GAP_STEPS` times the track's median step). Training integrates one
    RK4 step per interval, and a smoother's velocity across a long gap is a guess: a track with a
    tracking outage becomes pieces, each a trajectory of its own. A split track's pieces are named
    ``ID#1``, ``ID#2``, … in time order; a piece with fewer than :data:`MIN_SAMPLES` samples is
    dropped (and counted)."""
    pieces: list[Trajectory] = []
    track: list[int] = []
    gaps = split_tracks = short_pieces = short_rows = 0
    for k, tr in enumerate(trajectories):
        steps = np.diff(tr.t)
        limit = GAP_STEPS * float(np.median(steps)) if max_gap is None else max_gap
        cuts = np.flatnonzero(steps > limit) + 1
        if cuts.size == 0:
            pieces.append(tr)
            track.append(k)
            continue
        gaps += int(cuts.size)
        split_tracks += 1
        bounds = np.r_[0, cuts, tr.t.size]
        for j, (a, b) in enumerate(itertools.pairwise(bounds)):
            if b - a < MIN_SAMPLES:
                short_pieces += 1
                short_rows += int(b - a)
                continue
            pieces.append(tr.take(slice(a, b), f"{tr.traj_id}#{j + 1}"))
            track.append(k)
    return GapSplit(pieces, np.asarray(track, dtype=np.int64), gaps, split_tracks, short_pieces, short_rows)
