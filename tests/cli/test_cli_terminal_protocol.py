"""The one progress protocol as the library speaks it: stages "k/N: what" that begin and end in
pairs, counts that move up to their totals (shprobe.progress.Recorder reads them)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.progress import Fraction, Recorder, Steps


def balanced(rec: Recorder) -> None:
    """Every stage ends, in nesting order; a stage's counts rise to at most its total."""
    open_: list[float | None] = []
    done: list[float] = []
    for kind, a, b in rec.events:
        if kind == "begin":
            open_.append(b)
            done.append(0.0)
        elif kind == "update":
            assert open_, "an update outside a stage"
            assert a >= done[-1] and (open_[-1] is None or a <= open_[-1])
            done[-1] = a
        else:
            open_.pop()
            done.pop()
    assert not open_


def test_steps_number_the_stages_and_close_on_error():
    rec = Recorder()
    with pytest.raises(RuntimeError), Steps(rec, 3) as step:
        step("one")
        bar = step("two", total=4)
        bar.advance(2)
        raise RuntimeError
    assert rec.stages == ["1/3: one", "2/3: two"]
    assert [e[0] for e in rec.events] == ["begin", "end", "begin", "update", "end"]
    with Steps(None, 2) as step:  # None: quiet, and still a Stage to advance
        step("x").advance()


def test_fraction_reports_the_outer_countable_stage():
    got: list[float] = []
    rep = Fraction(got.append)
    rep.begin("outer", 10)
    rep.update(5)
    rep.begin("inner", 3)
    rep.update(3)  # not the outer stage's
    rep.end()
    rep.update(10)
    rep.end()
    assert got == [0.5, 1.0]


def test_report_stages():
    from shprobe.probes.env import Env
    from shprobe.report import probe_report
    from shprobe.report.probe import REPORT_STAGES

    rad = (np.random.default_rng(2).random((8, 16, 3)) + 0.1).astype(np.float32)
    rec = Recorder()
    probe_report(Env(rad, "latlong"), map_height=4, render_size=16, progress=rec)
    balanced(rec)
    outer = [s for s in rec.stages if "/" in s.split(":")[0]]
    assert [s.split(":")[0] for s in outer] == [f"{k}/{REPORT_STAGES}"
                                                for k in range(1, REPORT_STAGES + 1)]
    # the brute-force map counts its products inside its stage, up to 2N² normals × pixels
    begin = next(e for e in rec.events if e[0] == "begin" and "brute force" in str(e[1]))
    assert begin[2] == 2 * 4 * 4 * 8 * 16
    i = rec.events.index(begin)
    assert rec.events[i - 1][1] == f"2/{REPORT_STAGES}: exact irradiance map 8x4"
    ups = [e[1] for e in rec.events[i + 1:] if e[0] == "update"]
    assert ups and ups[-1] == begin[2]


def test_study_counts_its_bases():
    from shprobe.hbasis.rivals import all_bases
    from shprobe.hbasis.study import run_study

    rec = Recorder()
    run_study(10, seed=1, progress=rec)
    balanced(rec)
    assert [s.split(":")[0] for s in rec.stages] == ["1/4", "2/4", "3/4", "4/4"]
    n = len(all_bases())
    i = rec.events.index(("begin", f"3/4: the IMSE of {n} bases", n))
    assert [e[1] for e in rec.events[i + 1:i + 1 + n]] == list(range(1, n + 1))


def test_study_cost_counts_its_arrays():
    """The study's estimate is the bytes of the arrays it holds at once: the signals' SH and
    two copies of their non-zero irradiance coefficients (Â_l ≠ 0)."""
    from shprobe.hbasis.study import LMAX_SIGNAL, random_signals, study_cost
    from shprobe.sh import degrees
    from shprobe.sh.zonal import clamped_cosine_factors

    sig = random_signals(5, seed=3)
    nonzero = int(np.count_nonzero(clamped_cosine_factors(LMAX_SIGNAL)[degrees(LMAX_SIGNAL)]))
    sh = sig.sh(LMAX_SIGNAL)
    assert study_cost(5).nbytes == sh.nbytes + 2 * sh[:, :nonzero].nbytes
    assert study_cost(200_000).long and not study_cost(2000).long
