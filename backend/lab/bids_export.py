"""A study as a BIDS dataset with the motion modality (BIDS 1.9, "Motion").

Layout (entities as BIDS defines them):

    dataset_description.json, README, participants.tsv/.json
    sub-<code>/ses-<session id>/motion/
        sub-<code>_ses-<n>_task-<task>_tracksys-exo_acq-<controller>_run-<k>_motion.tsv
        ... _motion.json, _channels.tsv
        sub-<code>_ses-<n>_task-<task>_acq-<controller>_run-<k>_events.tsv/.json
    phenotype/<questionnaire>.tsv/.json
    sourcedata/sub-<code>/ses-<n>/<attached XDF files>

One motion file per trial that ran: the exoskeleton's hip angles, velocities, torques,
lock commands and mechanism states, and the intent estimator's posteriors, one row per
tick (motion files have no header; `_channels.tsv` names the columns). Events are the
experimenter's lifts (trial segments), each side's lock command and mechanism edges,
and the markers. Only de-identified fields leave: the participant's code, age, sex,
height and mass; no consent date, no notes, no account.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.db.evidence_tables import LockEvent, Trial, TrialSegment
from backend.db.lab import Marker, XdfAttachment
from backend.db.models import (
    ConditionLabel,
    Participant,
    QuestionnaireResponse,
    Study,
    StudySession,
)
from controller.device.base import SAMPLE_RATE_HZ

#: The BIDS version the layout follows (motion entered the specification in 1.9.0).
BIDS_VERSION = "1.9.0"
TRACKSYS = "exo"


@dataclass(frozen=True)
class Channel:
    """A motion channel: tick field, BIDS type, component, tracked point, unit."""

    field: str
    type: str
    component: str
    tracked_point: str
    units: str
    description: str


# Hip flexion is a rotation about the medio-lateral axis, named "x" here (stated in
# motion.json); posteriors, commands and states have no component in BIDS' sense.
CHANNELS: tuple[Channel, ...] = (
    Channel("t", "LATENCY", "n/a", "n/a", "s", "device timestamp of the sample"),
    Channel("q_left", "JNTANG", "x", "LeftHip", "rad",
            "left hip flexion after calibration, flexion positive"),
    Channel("q_right", "JNTANG", "x", "RightHip", "rad",
            "right hip flexion after calibration, flexion positive"),
    Channel("q_raw_left", "JNTANG", "x", "LeftHip", "rad",
            "left hip flexion from the encoder, before calibration"),
    Channel("q_raw_right", "JNTANG", "x", "RightHip", "rad",
            "right hip flexion from the encoder, before calibration"),
    Channel("omega_left", "MISC", "x", "LeftHip", "rad/s",
            "left hip flexion velocity (Kalman filter)"),
    Channel("omega_right", "MISC", "x", "RightHip", "rad/s",
            "right hip flexion velocity (Kalman filter)"),
    Channel("torque_left", "MISC", "n/a", "LeftHip", "N.m",
            "left exoskeleton extension torque from the actuator model"),
    Channel("torque_right", "MISC", "n/a", "RightHip", "N.m",
            "right exoskeleton extension torque from the actuator model"),
    Channel("post_squat", "MISC", "n/a", "n/a", "n/a", "posterior probability of a squat"),
    Channel("post_stoop_left", "MISC", "n/a", "n/a", "n/a",
            "posterior probability of a stoop to the left"),
    Channel("post_stoop_right", "MISC", "n/a", "n/a", "n/a",
            "posterior probability of a stoop to the right"),
    Channel("post_other", "MISC", "n/a", "n/a", "n/a", "posterior probability of other"),
    Channel("lock_left", "MISC", "n/a", "LeftHip", "n/a", "left solenoid command (0/1)"),
    Channel("lock_right", "MISC", "n/a", "RightHip", "n/a", "right solenoid command (0/1)"),
    Channel("locked_left", "MISC", "n/a", "LeftHip", "n/a",
            "left ratchet engaged, from the device (0/1)"),
    Channel("locked_right", "MISC", "n/a", "RightHip", "n/a",
            "right ratchet engaged, from the device (0/1)"),
)


def label(text: str) -> str:
    """A BIDS entity label: letters and digits only."""
    out = re.sub(r"[^A-Za-z0-9]", "", text)
    return out or "x"


def _tsv(header: list[str] | None, rows: list[list[Any]]) -> str:
    out = io.StringIO()
    w = csv.writer(out, delimiter="\t", lineterminator="\n")
    if header is not None:
        w.writerow(header)
    for row in rows:
        w.writerow([_cell(v) for v in row])
    return out.getvalue()


def _cell(v: Any) -> Any:
    if v is None or v == "":
        return "n/a"
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, float):
        return "n/a" if not math.isfinite(v) else repr(v)
    return v


def _json(doc: dict[str, Any]) -> str:
    return json.dumps(doc, indent=2) + "\n"


def dataset_files(engine: Engine, db: Session, study_id: int,
                  site: str | None = None) -> Iterator[tuple[str, bytes]]:
    """Every file of the study's BIDS dataset as (relative path, content).

    Withdrawn participants are left out, and with `site` everyone of another site (a
    member limited to one site exports only that site)."""
    study = db.get(Study, study_id)
    if study is None:
        raise ValueError(f"study {study_id} does not exist")
    yield "dataset_description.json", _json({
        "Name": study.name, "BIDSVersion": BIDS_VERSION, "DatasetType": "raw",
        "GeneratedBy": [{"Name": "ExoStudy", "Version": "0.1.0",
                         "Description": "quasi-passive hip exoskeleton study manager"}],
    }).encode()
    yield "README", (f"{study.name}\n\n{study.description}\n\nExported by ExoStudy: one "
                     "motion file per evaluation trial (the exoskeleton's hip encoders, "
                     "its torque model, lock commands and states, and the intent "
                     "estimator's posteriors at 100 Hz), with events (lifts, lock edges, "
                     "markers) and questionnaires as phenotype files.\n").encode()
    chosen = (Participant.study_id == study_id) & Participant.withdrawn_at.is_(None)
    if site is not None:
        chosen = chosen & (Participant.site == site)
    participants = list(db.scalars(select(Participant).where(chosen).order_by(Participant.id)))
    subs = {p.id: label(p.code) for p in participants}
    if len(set(subs.values())) != len(subs):
        subs = {p.id: f"{label(p.code)}{p.id}" for p in participants}
    yield "participants.tsv", _tsv(
        ["participant_id", "age", "sex", "height", "weight"],
        [[f"sub-{subs[p.id]}", p.age, p.sex, p.height_m, p.mass_kg]
         for p in participants]).encode()
    yield "participants.json", _json({
        "participant_id": {"Description": "pseudonymous participant code"},
        "age": {"Description": "age", "Units": "year"},
        "sex": {"Description": "sex as stated by the participant"},
        "height": {"Description": "body height", "Units": "m"},
        "weight": {"Description": "body mass", "Units": "kg"},
    }).encode()
    for p in participants:
        sessions = list(db.scalars(select(StudySession).where(
            StudySession.participant_id == p.id).order_by(StudySession.id)))
        blinded = {c.controller: c.label for c in db.scalars(
            select(ConditionLabel).where(ConditionLabel.participant_id == p.id))}
        for sess in sessions:
            yield from _session_files(engine, db, subs[p.id], sess, blinded)
    yield from _phenotype(db, subs)


def _session_files(engine: Engine, db: Session, sub: str, sess: StudySession,
                   blinded: dict[str, str]) -> Iterator[tuple[str, bytes]]:
    ses = f"ses-{sess.id}"
    trials = list(db.scalars(select(Trial).where(Trial.session_id == sess.id,
                                                 Trial.run_id.is_not(None))
                             .order_by(Trial.planned_order, Trial.id)))
    counts: dict[tuple[str, str], int] = {}
    scans: list[list[Any]] = []
    for trial in trials:
        assert trial.run_id is not None
        cols = tick_queries.columns(engine, trial.run_id)
        if cols["t"].size == 0:
            continue
        task, acq = label(trial.task), label(trial.controller)
        counts[(task, acq)] = k = counts.get((task, acq), 0) + 1
        # BIDS' entity order: task, tracksys, acq, run.
        folder = f"sub-{sub}/{ses}/motion/"
        base = f"sub-{sub}_{ses}_task-{task}"
        stem = f"{folder}{base}_tracksys-{TRACKSYS}_acq-{acq}_run-{k}"
        rows = [[float(cols[c.field][i]) if c.units != "n/a" or c.field.startswith("post")
                 else int(cols[c.field][i]) for c in CHANNELS] for i in range(cols["t"].size)]
        yield f"{stem}_motion.tsv", _tsv(None, rows).encode()
        yield f"{stem}_channels.tsv", _tsv(
            ["name", "component", "type", "tracked_point", "units", "description"],
            [[c.field, c.component, c.type, c.tracked_point, c.units, c.description]
             for c in CHANNELS]).encode()
        t = cols["t"]
        duration = float(t[-1] - t[0]) + 1.0 / SAMPLE_RATE_HZ
        yield f"{stem}_motion.json", _json({
            "TaskName": trial.task,
            "TaskDescription": f"{trial.task} with the exoskeleton under the "
                               f"{trial.controller} controller (blinded label "
                               f"{blinded.get(trial.controller, 'n/a')})",
            "SamplingFrequency": SAMPLE_RATE_HZ,
            "SamplingFrequencyEffective": (t.size - 1) / float(t[-1] - t[0])
            if t.size > 1 and t[-1] > t[0] else SAMPLE_RATE_HZ,
            "RecordingDuration": duration,
            "TrackingSystemName": "quasi-passive hip exoskeleton encoders (component x: "
                                  "rotation about the medio-lateral axis, flexion positive)",
            "Manufacturer": "ExoStudy",
            "ManufacturersModelName": "quasi-passive hip exoskeleton",
            "SoftwareVersions": "ExoStudy 0.1.0",
            "TrackedPointsCount": 2,
            "JNTANGChannelCount": 4, "LATENCYChannelCount": 1, "MISCChannelCount": 12,
            "MotionChannelCount": len(CHANNELS),
            "MissingValues": "n/a",
        }).encode()
        scans.append([f"motion/{stem.rsplit('/', 1)[1]}_motion.tsv", trial.id, trial.controller,
                      blinded.get(trial.controller), trial.status,
                      trial.started_at.isoformat() if trial.started_at else None])
        ev_rows = _events(db, trial, float(t[0]), cols)
        yield f"{folder}{base}_acq-{acq}_run-{k}_events.tsv", _tsv(
            ["onset", "duration", "trial_type", "side", "value", "source"], ev_rows).encode()
        yield f"{folder}{base}_acq-{acq}_run-{k}_events.json", _json({
            "onset": {"Description": "seconds from the first sample of the motion file",
                      "Units": "s"},
            "duration": {"Description": "lift duration; 0 for instantaneous events",
                         "Units": "s"},
            "trial_type": {"Description": "lift (experimenter's segment), lock command "
                           "and mechanism edges per side, markers",
                           "Levels": {"lift": "a lift marked by the experimenter",
                                      "command_on": "solenoid command on",
                                      "command_off": "solenoid command off",
                                      "engaged": "ratchet engaged",
                                      "released": "ratchet released",
                                      "marker": "an event marker (console, LSL or system)"}},
            "side": {"Description": "left or right hip, n/a for both"},
            "value": {"Description": "lift label, peak torque (N.m) of an engagement, or "
                      "the marker's label"},
            "source": {"Description": "segment, lock_events, console, lsl or system"},
        }).encode()
    if scans:
        prefix = f"sub-{sub}/{ses}/sub-{sub}_{ses}_scans"
        yield f"{prefix}.tsv", _tsv(["filename", "trial_id", "controller", "blinded_label",
                                     "outcome", "started"], scans).encode()
        yield f"{prefix}.json", _json({
            "filename": {"Description": "the trial's motion file"},
            "trial_id": {"Description": "ExoStudy's trial id"},
            "controller": {"Description": "the exoskeleton controller of the trial"},
            "blinded_label": {"Description": "the label the participant knew it by"},
            "outcome": {"Description": "completed or aborted"},
            "started": {"Description": "when the trial started (UTC, ISO 8601)"},
        }).encode()
    for att in db.scalars(select(XdfAttachment).where(XdfAttachment.session_id == sess.id)
                          .order_by(XdfAttachment.id)):
        yield (f"sourcedata/sub-{sub}/{ses}/{att.id}_{label(att.filename.removesuffix('.xdf'))}"
               ".xdf", att.content)


def _events(db: Session, trial: Trial, t0: float, cols: dict[str, Any]) -> list[list[Any]]:
    rows: list[list[Any]] = []
    t = cols["t"]
    for s in db.scalars(select(TrialSegment).where(TrialSegment.trial_id == trial.id)):
        if 0 <= s.start < t.size and s.end < t.size:
            rows.append([float(t[s.start] - t0), float(t[s.end] - t[s.start]), "lift", "n/a",
                         s.label, "segment"])
    for e in db.scalars(select(LockEvent).where(LockEvent.trial_id == trial.id)):
        rows.append([e.t - t0, 0.0, e.kind, e.side, e.torque_peak, "lock_events"])
    for m in db.scalars(select(Marker).where(Marker.trial_id == trial.id)):
        if m.t is not None:
            rows.append([max(m.t - t0, 0.0), 0.0, "marker", "n/a",
                         m.label + (f": {m.note}" if m.note else ""), m.source])
    rows.sort(key=lambda r: (r[0], str(r[2])))
    return rows


def _phenotype(db: Session, subs: dict[int, str]) -> Iterator[tuple[str, bytes]]:
    responses = list(db.scalars(select(QuestionnaireResponse).where(
        QuestionnaireResponse.participant_id.in_(list(subs) or [-1]))
        .order_by(QuestionnaireResponse.id)))
    by_key: dict[str, list[QuestionnaireResponse]] = {}
    for r in responses:
        by_key.setdefault(r.instrument_key, []).append(r)
    for key, rs in by_key.items():
        items = sorted({str(k) for r in rs for k in r.answers})
        name = label(key).lower()
        yield f"phenotype/{name}.tsv", _tsv(
            ["participant_id", "condition_label", "instrument_version", "score", *items],
            [[f"sub-{subs[r.participant_id]}", r.condition_label, r.instrument_version,
              r.score, *[r.answers.get(i) for i in items]] for r in rs]).encode()
        doc: dict[str, Any] = {
            "MeasurementToolMetadata": {"Description": f"questionnaire {key}"},
            "participant_id": {"Description": "pseudonymous participant code"},
            "condition_label": {"Description": "blinded condition the answers are about"},
            "instrument_version": {"Description": "version of the questionnaire definition"},
            "score": {"Description": "total score computed at submission"},
        }
        for i in items:
            doc[i] = {"Description": f"answer to item {i}"}
        yield f"phenotype/{name}.json", _json(doc).encode()
