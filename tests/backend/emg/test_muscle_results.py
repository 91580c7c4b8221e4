"""Muscle activity in a study's results, from EMG in the store: lifts from the
experimenter's markers (trials without ticks, as a "no exoskeleton" trial in a lab),
synthetic EMG whose amplitude each condition sets, and the bad input of the issue: a
stream that stops inside a trial, a trial with no EMG, an MVC below task activity."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db import migrate
from backend.db.emg import EmgAnalysisSettings, EmgMontage, EmgRecording, MvcStep
from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.db.models import Participant, Study, StudySession
from backend.emg import muscle_results, recordings, store
from backend.schemas.muscle_results import MuscleResultsOut
from controller.emg.processing import EmgProcessing
from controller.sim.muscles import CHANNELS, channel_label
from controller.sim.surface_emg import SurfaceEmgGenerator

FS = 2000.0
BASE = 5000.0  # the session clock at the recording's first sample
TRIAL_S, GAP_S = 8.0, 2.0
LIFTS = ((2.0, 4.0, "squat"), (5.0, 7.0, "stoop_left"))
#: Activation of every muscle during the lifts under each condition (0.02 at rest).
LEVELS = {"umc": 0.6, "pec": 0.56, "springs_free": 0.8, "no_exoskeleton": 0.8}
CHANS = CHANNELS[:3]


@pytest.fixture
def settings(settings: Settings, tmp_path: Path) -> Settings:
    """EMG files in the test's folder."""
    return settings.model_copy(update={"emg_dir": tmp_path / "emg"})


def _marker(db: Session, sess: int, trial: int | None, t: float, label: str,
            note: str = "", source: str = "console") -> Marker:
    m = Marker(session_id=sess, trial_id=trial, t=None, lsl_time=BASE + t, label=label,
               note=note, source=source)
    db.add(m)
    db.flush()
    return m


def _activation(order: list[str], scale: float, mvc_level: float | None) -> np.ndarray:
    """100 Hz activation of the whole session: optional MVC first, then the trials."""
    n = round((len(order) * (TRIAL_S + GAP_S) + (4.0 if mvc_level else 0.0)) * 100)
    act = np.full((n, len(CHANS)), 0.02)
    t0 = 4.0 if mvc_level else 0.0
    if mvc_level:
        act[100:300] = mvc_level
    for k, cond in enumerate(order):
        for a, b, _kind in LIFTS:
            i0 = round((t0 + k * (TRIAL_S + GAP_S) + a) * 100)
            act[i0:round((t0 + k * (TRIAL_S + GAP_S) + b) * 100)] = LEVELS[cond] * scale
    return act


def _study(db_url: str, settings: Settings, participants: int = 3,
           normalisation: str = "task_peak", mvc_level: float | None = None,
           keep_s: float | None = None, order: list[str] | None = None,
           restart_s: float | None = None) -> dict[str, Any]:
    """Participants with one session each: four trials (rotated order), lifts marked by
    the experimenter, one EMG recording of the session (`keep_s`: only its first so
    many seconds, a stream that stopped)."""
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    out: dict[str, Any] = {"sessions": []}
    with Session(engine) as db:
        study = Study(name="EMG study")
        db.add(study)
        db.flush()
        out["study"] = study.id
        db.add(EmgAnalysisSettings(study_id=study.id, processing=EmgProcessing(
            normalisation=normalisation).to_dict(), mains_hz=50))  # type: ignore[arg-type]
        montage = EmgMontage(study_id=study.id, version=1, placement_scheme="SENIAM",
                             channels=[{"label": channel_label(m, s), "muscle": m, "side": s}
                                       for m, s in CHANS])
        db.add(montage)
        db.flush()
        for j in range(participants):
            p = Participant(study_id=study.id, code=f"P{j + 1:02d}")
            db.add(p)
            db.flush()
            sess = StudySession(participant_id=p.id, kind="evaluation", precompression_pct=25)
            db.add(sess)
            db.flush()
            out["sessions"].append(sess.id)
            base_order = order or list(LEVELS)
            conds = base_order[j % len(base_order):] + base_order[:j % len(base_order)]
            t0 = 0.0
            if mvc_level:
                a = _marker(db, sess.id, None, 1.0, "mvc_start", "all both rep 1")
                b = _marker(db, sess.id, None, 3.0, "mvc_stop", "all both rep 1")
                for i, m in enumerate(dict.fromkeys(m for m, _s in CHANS)):
                    db.add(MvcStep(session_id=sess.id, planned_order=i, muscle=m, side="both",
                                   repetitions=1, repetitions_done=[
                                       {"rep": 1, "start_marker_id": a.id,
                                        "stop_marker_id": b.id}]))
                t0 = 4.0
            for k, cond in enumerate(conds):
                trial = Trial(session_id=sess.id, controller=cond, task="squat-sequence",
                              planned_order=k, status="completed")
                db.add(trial)
                db.flush()
                start = t0 + k * (TRIAL_S + GAP_S)
                _marker(db, sess.id, trial.id, start, "trial_start", source="system")
                _marker(db, sess.id, trial.id, start + TRIAL_S, "trial_stop", source="system")
                for a_s, b_s, kind in LIFTS:
                    _marker(db, sess.id, trial.id, start + a_s, "lift_start", kind)
                    _marker(db, sess.id, trial.id, start + b_s, "lift_stop")
            db.commit()
            act = _activation(conds, 1.0 + 0.05 * j, mvc_level)
            gen = SurfaceEmgGenerator(len(CHANS), seed=10 + j)
            x = gen.push(act).samples
            if keep_s is not None:
                x = x[:round(keep_s * FS)]
            cut = round(restart_s * FS) if restart_s is not None else len(x)
            recordings.store_blocks(db, settings, sess.id, montage, "simulated", FS,
                                    [(None, x[:cut])], BASE, "test: offset stated")
            if restart_s is not None:  # the stream came back 0.5 s later: a new recording
                resume = cut + round(0.5 * FS)
                recordings.store_blocks(db, settings, sess.id, montage, "simulated", FS,
                                        [(None, x[resume:])], BASE + resume / FS,
                                        "test: offset stated", flags=["stream_restarted"])
    out["engine"] = engine
    return out


def _results(made: dict[str, Any], settings: Settings) -> muscle_results.MuscleResults:
    with Session(made["engine"]) as db:
        return muscle_results.study_muscle_results(made["engine"], db,
                                                   store.emg_folder(settings), made["study"])


def test_reductions_follow_the_conditions_amplitudes(db_url: str, settings: Settings) -> None:
    made = _study(db_url, settings)
    res = _results(made, settings)
    assert len(res.trials) == 12
    assert all(len(t.lifts) == 2 and t.lift_source == "markers" for t in res.trials)
    assert all(lf.outcome is not None for t in res.trials for lf in t.lifts)
    assert res.channels == [f"{m}_{s}" for m, s in CHANS]
    assert res.baselines() == ["springs_free", "no_exoskeleton"]
    # Task peak: the largest lift envelope of the session is 1 on every channel.
    peaks = [max(lf.outcome.lift.peak[c] for t in res.trials if t.session_id == sid
                 for lf in t.lifts if lf.outcome) for sid in made["sessions"] for c in range(3)]
    assert np.allclose(peaks, 1.0)
    reds = {(r["condition"], r["baseline"], r["channel"]): r for r in res.reductions()
            if r["group"] == "all" and r["metric"] == "mean"}
    for ch in res.channels:
        umc = reds[("umc", "no_exoskeleton", ch)]
        # Activation 0.6 against 0.8 on top of 0.02 rest: the envelope falls by about 25 %.
        assert 18.0 < umc["mean_pct"] < 30.0
        assert umc["ci_low"] > 10.0 and umc["ci_high"] < 35.0
        pec = reds[("pec", "no_exoskeleton", ch)]
        assert pec["mean_pct"] > umc["mean_pct"]
        same = reds[("springs_free", "no_exoskeleton", ch)]
        assert abs(same["mean_pct"]) < 5.0 and same["ci_low"] < 0.0 < same["ci_high"]
    rm = [r for r in res.repeated() if r["metric"] == "mean"]
    assert len(rm) == 3 and all(r["n"] == 3 and len(r["conditions"]) == 4 for r in rm)
    # Per kind too, and the outputs carry the method.
    assert {r["group"] for r in res.summary()} == {"all", "squat", "stoop_left"}
    lifts_csv = res.csv("lifts")
    assert "# processing:" in lifts_csv and "'normalisation': 'task_peak'" in lifts_csv
    doc = res.document()
    assert doc["method"]["processing"]["envelope_hz"] == 6.0
    # The route's response model names every key the document has, and keeps them all.
    assert MuscleResultsOut.model_validate(doc).model_dump() == doc
    assert "Reduction of the mean envelope" in res.markdown()
    for name in muscle_results.FIGURES:
        fig = res.figure(name)
        assert fig.png[:4] == b"\x89PNG" and len(fig.svg) > 1000
    # The reduction figure computes the one family it draws: the rows of the whole.
    drawn = res._reductions(("all",), ("mean",))[0]
    assert drawn and drawn == [r for r in res.reductions()
                               if r["group"] == "all" and r["metric"] == "mean"]
    made["engine"].dispose()


def test_a_stream_that_stops_mid_trial_and_a_trial_without_emg(
        db_url: str, settings: Settings) -> None:
    """The recording ends 6 s into the third trial: its second lift has no EMG and is
    listed with the flag; the fourth trial has none at all; nothing else is lost."""
    made = _study(db_url, settings, participants=1, keep_s=2 * (TRIAL_S + GAP_S) + 6.0)
    res = _results(made, settings)
    by = {t.condition: t for t in res.trials}
    third, fourth = by["springs_free"], by["no_exoskeleton"]
    assert [lf.outcome is not None for lf in third.lifts] == [True, False]
    assert third.lifts[1].flags == [muscle_results.NO_EMG]
    assert "1 of 2 lifts have no EMG" in third.note
    assert muscle_results.NO_EMG in fourth.flags and "no EMG recording" in fourth.note
    assert all(lf.outcome is None for lf in fourth.lifts)
    assert all(lf.outcome is not None for c in ("umc", "pec") for lf in by[c].lifts)
    header, rows = res.lift_rows()
    flags = [r[header.index("flags")] for r in rows if r[0] == fourth.trial_id]
    assert flags and all("no_emg" in f for f in flags)
    assert any(f"trial {fourth.trial_id}" in n for n in res.notes)
    made["engine"].dispose()


def test_an_interrupted_recording_is_measured_and_a_damaged_file_costs_its_later_lifts(
        db_url: str, settings: Settings) -> None:
    """A recording a killed server left (finalised at the next start as `interrupted`,
    one recording for the whole session) holds the trials before the crash: they are
    measured, with its flag. A chunk that does not read back (the sixth, 25-30 s into
    the session) costs the lifts after it, which their trials say, and nothing else:
    the study's results are still computed."""
    made = _study(db_url, settings, participants=1, order=list(LEVELS))
    with Session(made["engine"]) as db:
        rec = db.scalars(select(EmgRecording)).one()
        rec.status = "interrupted"
        rec.quality = {**rec.quality, "flags": [*rec.quality["flags"], "interrupted"]}
        db.commit()
        rid = rec.id
    res = _results(made, settings)
    assert [t.condition for t in res.trials] == list(LEVELS)
    assert all(lf.outcome is not None for t in res.trials for lf in t.lifts)
    assert all("interrupted" in t.flags for t in res.trials)

    path = store.emg_folder(settings) / f"{rid}.emgc"
    data = path.read_bytes()
    heads = [i for i in range(len(data)) if data.startswith(b'{"rows":', i)]
    assert len(heads) == 8  # 40 s at 2 kHz, 10,000 rows a chunk
    path.write_bytes(data[:heads[5]] + b"[" + data[heads[5] + 1:])
    res = _results(made, settings)
    measured = {t.condition: [lf.outcome is not None for lf in t.lifts] for t in res.trials}
    # Trials at 0-8, 10-18, 20-28 and 30-38 s; lifts 2-4 and 5-7 s into each.
    assert measured == {"umc": [True, True], "pec": [True, True],
                        "springs_free": [True, False], "no_exoskeleton": [False, False]}
    flagged = {t.condition for t in res.trials if muscle_results.FILE_DAMAGED in t.flags}
    assert flagged == {"springs_free", "no_exoskeleton"}
    third = next(t for t in res.trials if t.condition == "springs_free")
    assert f"EMG recording {rid} does not read back after" in third.note
    assert "chunk header is not JSON" in third.note
    assert res.document()["trials"]  # the study's results, not a refusal
    # Normalised to the session's task peak: the lost lifts are not in the reference.
    assert any("the lifts a damaged file lost are not in it" in n for n in res.notes)

    # A file that is gone: every trial it covered says so, nothing is measured from it.
    path.unlink()
    res = _results(made, settings)
    assert all(muscle_results.FILE_DAMAGED in t.flags and "its file is missing" in t.note
               for t in res.trials)
    assert not any(lf.outcome for t in res.trials for lf in t.lifts)
    made["engine"].dispose()


def test_damage_after_a_trials_lifts_and_after_the_mvc_costs_them_nothing(
        db_url: str, settings: Settings) -> None:
    """The last chunk (40-44 s of a session whose MVC is at 1-3 s) does not read back:
    the MVC reference stands, the last trial's first lift (36-38 s) and every earlier
    one are measured, and only the last trial, whose second lift (39-41 s) runs into the
    damage, is flagged."""
    made = _study(db_url, settings, participants=1, normalisation="mvc", mvc_level=0.9,
                  order=list(LEVELS))
    whole = _results(made, settings)
    with Session(made["engine"]) as db:
        rid = db.scalars(select(EmgRecording)).one().id
    path = store.emg_folder(settings) / f"{rid}.emgc"
    data = path.read_bytes()
    heads = [i for i in range(len(data)) if data.startswith(b'{"rows":', i)]
    assert len(heads) == 9  # 44 s at 2 kHz
    path.write_bytes(data[:heads[-1]] + b"[" + data[heads[-1] + 1:])
    res = _results(made, settings)
    (sid,) = made["sessions"]
    assert muscle_results.NO_MVC not in res.references[sid].flags
    assert res.references[sid].values == whole.references[sid].values
    flagged = [t.condition for t in res.trials if muscle_results.FILE_DAMAGED in t.flags]
    assert flagged == ["no_exoskeleton"]
    measured = {t.condition: [lf.outcome is not None for lf in t.lifts] for t in res.trials}
    assert measured["springs_free"] == [True, True]
    assert measured["no_exoskeleton"] == [True, False]
    made["engine"].dispose()


def test_mvc_below_task_activity_is_flagged_and_kept(db_url: str, settings: Settings) -> None:
    made = _study(db_url, settings, participants=1, normalisation="mvc", mvc_level=0.3)
    res = _results(made, settings)
    ref = res.references[made["sessions"][0]]
    assert ref.method == "mvc"
    assert muscle_results.EXCEEDS_MVC in ref.flags
    assert set(ref.exceeds) == set(res.channels)
    assert all(2.0 < v < 3.5 for v in ref.exceeds.values())  # 0.8 against 0.3
    peak = max(lf.outcome.lift.peak[0] for t in res.trials for lf in t.lifts if lf.outcome)
    assert peak > 2.0  # shown above 1, not clipped
    assert any("exceeds the MVC" in n for n in res.notes)
    header, rows = res.lift_rows()
    assert any("exceeds_mvc:" in r[header.index("flags")] for r in rows)
    made["engine"].dispose()


def test_mvc_study_without_mvc_reports_volts(db_url: str, settings: Settings) -> None:
    made = _study(db_url, settings, participants=1, normalisation="mvc")
    res = _results(made, settings)
    ref = res.references[made["sessions"][0]]
    assert ref.method == "none" and muscle_results.NO_MVC in ref.flags
    assert res.unit("mean") == "V"
    made["engine"].dispose()


def test_a_stream_that_restarts_mid_trial(db_url: str, settings: Settings) -> None:
    """The stream drops 5.5 s into the second trial (inside its second lift) and comes
    back half a second later as a second recording: the lift across the break has no
    EMG and says so, every other lift is measured in the recording that holds it, and
    the later trials carry the restart's flag."""
    made = _study(db_url, settings, participants=1, restart_s=TRIAL_S + GAP_S + 5.5)
    res = _results(made, settings)
    by = {t.condition: t for t in res.trials}
    second, third = by["pec"], by["springs_free"]
    assert [lf.outcome is not None for lf in second.lifts] == [True, False]
    assert second.lifts[1].flags == [muscle_results.NO_EMG]
    assert len(set(second.recordings)) == 2
    assert second.lifts[0].recording_id != third.lifts[0].recording_id
    assert "stream_restarted" in third.flags
    assert all(lf.outcome is not None for c in ("umc", "springs_free", "no_exoskeleton")
               for lf in by[c].lifts)
    made["engine"].dispose()


def _lift(index: int, kind: str, level: float) -> muscle_results.LiftEmg:
    from controller.emg.outcomes import LiftOutcome, WindowOutcome

    w = WindowOutcome((level,), (level,), (level,), 1.0)
    return muscle_results.LiftEmg(index, kind, 0.0, 1.0, 1, LiftOutcome(w))


def test_conditions_list_each_controllers_variants_after_its_plain_name() -> None:
    keys = ["umc+personal", "no_exoskeleton", "eumc+priors", "umc", "springs_free", "pec",
            "eumc", "umc+personal+priors", "umc+priors"]
    trials = [muscle_results.TrialEmg(k, 1, "P01", c, "lifting", "markers",
                                      lifts=[_lift(0, "squat", 0.5)])
              for k, c in enumerate(keys)]
    res = muscle_results.MuscleResults(1, {}, 50, ["ES_left"], trials)
    assert res.conditions() == ["umc", "umc+personal", "umc+priors", "umc+personal+priors",
                                "eumc", "eumc+priors", "pec", "springs_free",
                                "no_exoskeleton"]


def test_a_baseline_with_only_some_lift_kinds_is_a_stated_gap() -> None:
    """The attack: the baseline trials hold squats only, so the stoop groups have no
    baseline; that family is reported as a gap, the squat reductions still computed."""
    trials = []
    for i, p in enumerate(("P01", "P02", "P03")):
        trials.append(muscle_results.TrialEmg(
            10 + i, 1, p, "springs_free", "lifting", "markers",
            lifts=[_lift(0, "squat", 1.0)]))
        trials.append(muscle_results.TrialEmg(
            20 + i, 1, p, "umc", "lifting", "markers",
            lifts=[_lift(0, "squat", 0.5 + 0.01 * i), _lift(1, "stoop_left", 0.4)]))
    res = muscle_results.MuscleResults(1, {}, 50, ["ES_left"], trials)
    reds = res.reductions()
    squat = [r for r in reds if r["group"] == "squat" and r["metric"] == "mean"]
    assert [round(r["mean_pct"], 1) for r in squat] == [49.0]
    assert {r["group"] for r in reds} == {"all", "squat"}
    gaps = res.reduction_gaps()
    assert {(g["group"], g["metric"]) for g in gaps} == {
        ("stoop_left", m) for m in muscle_results.METRICS}
    assert all(g["gap"].startswith("no baseline data") for g in gaps)
    doc = MuscleResultsOut.model_validate(res.document())
    assert len(doc.reduction_gaps) == 3
    assert res.csv("reductions").count("springs_free") == len(reds)


def test_reductions_without_the_baseline_raise_a_clear_value_error() -> None:
    from controller.evaluation import muscle_stats

    rows = [muscle_stats.OutcomeRow("P01", "umc", "ES_left", 1.0)]
    with pytest.raises(ValueError, match="baseline 'springs_free' has no outcome rows"):
        muscle_stats.reductions(rows, "springs_free")


def test_stopped_mid_trial_is_decided_from_the_spans_at_results_time(
        db_url: str, settings: Settings) -> None:
    """The attack: a live stream lost inside a trial whose stop was not yet known when
    the recording finished carries `stream_lost` but no `stopped_mid_trial`. The trial
    the recording ended in is flagged at results time; the trials it covered whole
    are not."""
    from backend.db.emg import EmgRecording
    from backend.emg.quality_summary import STOPPED_MID_TRIAL

    made = _study(db_url, settings, participants=1, keep_s=2 * (TRIAL_S + GAP_S) + 6.0)
    with Session(made["engine"]) as db:
        for rec in db.query(EmgRecording).all():  # as finished before the stop was known
            q = dict(rec.quality or {})
            q["flags"] = [f for f in q.get("flags", []) if f != STOPPED_MID_TRIAL] + [
                "stream_lost"]
            rec.quality = q
        db.commit()
    muscle_results.CACHE._entries.clear()
    res = _results(made, settings)
    by = {t.condition: t for t in res.trials}
    assert STOPPED_MID_TRIAL in by["springs_free"].flags
    assert "stream_lost" in by["springs_free"].flags
    assert all(STOPPED_MID_TRIAL not in by[c].flags for c in ("umc", "pec"))
    made["engine"].dispose()
