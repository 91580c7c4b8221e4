"""A study as a BIDS dataset with the motion modality (BIDS 1.9, "Motion") and, where
the session has EMG recordings, the EMG modality (BIDS 1.11, `backend.emg.bids`).

Layout (entities as BIDS defines them):

    dataset_description.json, README, participants.tsv/.json
    sub-<code>/ses-<kind><n>/motion/
        sub-<code>_ses-<n>_task-<task>_tracksys-exo_acq-<controller>_run-<k>_motion.tsv
        ... _motion.json, _channels.tsv
    sub-<code>/ses-<kind><n>/emg/
        sub-<code>_ses-<n>_task-<task>_acq-<controller>_run-<k>_emg.bdf, _emg.json,
        ... _channels.tsv, _events.tsv/.json (the motion events on the EMG file's axis)
        sub-<code>_ses-<n>_task-<task>_acq-<controller>_run-<k>_events.tsv/.json
    phenotype/<questionnaire>.tsv/.json
    sourcedata/sub-<code>/ses-<n>/<attached XDF files>

One motion file per trial that ran: the exoskeleton's hip angles, velocities, torques,
lock commands and mechanism states, and the intent estimator's posteriors, one row per
tick (motion files have no header; `_channels.tsv` names the columns). Events are the
experimenter's lifts (trial segments), each side's lock command and mechanism edges,
and the markers. Only de-identified fields leave: the participant's code, age, sex,
height and mass; no consent date, no notes, no account.

Sessions are named by kind and order (`ses-evaluation1`, `ses-datacollection1`), so one
visit has the same name for every subject. The blinding key leaves only in an owner's
export (`unblind`): otherwise files are named by the blinded label (`acq-A`) and
`*_scans.tsv` has neither `controller` nor `trial_id`. The sidecars of the tabular
files come from `backend.analysis.bids_dictionary`, the definition the export's README is
written from.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import bids_dictionary, data_dictionary, tick_queries
from backend.core.resources import version
from backend.db.emg import ANALYSED_STATUSES, EmgAnalysisSettings, EmgMontage, EmgRecording
from backend.db.evidence_tables import LockEvent, Trial, TrialSegment
from backend.db.lab import Marker, XdfAttachment
from backend.db.models import (
    ConditionLabel,
    Participant,
    QuestionnaireResponse,
    Run,
    Study,
    StudySession,
)
from backend.emg import bids as emg_bids
from backend.emg import store
from controller import spreadsheet
from controller.device.base import SAMPLE_RATE_HZ
from controller.emg.processing import EmgProcessing

#: The BIDS version the layout follows (motion entered the specification in 1.9.0, EMG
#: in 1.11.0).
BIDS_VERSION = "1.11.0"
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


#: The HED schema the events' `trial_type` annotations use (the validator ships it).
HED_VERSION = "8.3.0"
#: HED tags of each event type (Hierarchical Event Descriptors: what kind of event it
#: is, in words a search across datasets understands). Each row's `HED` cell groups them
#: with the side, so two events at one instant (both hips locking) stay two events.
EVENT_HED = {
    "lift": "Agent-action, Lift",
    "command_on": "Data-feature, Label/Lock-command-on",
    "command_off": "Data-feature, Label/Lock-command-off",
    "engaged": "Data-feature, Label/Ratchet-engaged",
    "released": "Data-feature, Label/Ratchet-released",
    "marker": "Data-marker",
}
#: Session labels per session kind (letters only, as BIDS labels must be).
SESSION_KIND = {"evaluation": "evaluation", "data_collection": "datacollection"}


class NothingToExportError(ValueError):
    """The study has nothing a BIDS dataset could hold (no trial with ticks)."""


def _tsv(header: list[str] | None, rows: list[list[Any]]) -> str:
    return spreadsheet.table_text(header, ([_cell(v) for v in row] for row in rows),
                                  delimiter="\t")


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


def _description(study: Study) -> dict[str, Any]:
    """dataset_description.json: the study's name and its dataset description (empty
    fields left out)."""
    info: dict[str, Any] = study.dataset_info or {}
    doc: dict[str, Any] = {"Name": study.name, "BIDSVersion": BIDS_VERSION,
                           "DatasetType": "raw", "HEDVersion": HED_VERSION}
    if info.get("license"):
        doc["License"] = info["license"]
    if info.get("authors"):
        doc["Authors"] = list(info["authors"])
    if info.get("funding"):
        doc["Funding"] = list(info["funding"])
    doc["GeneratedBy"] = [{"Name": "ExoStudy", "Version": version(),
                           "Description": "quasi-passive hip exoskeleton study manager"}]
    # The dataset is made from the study's records in ExoStudy (and the attached XDF
    # files, which are under sourcedata/).
    doc["SourceDatasets"] = [{"URL": "bids::sourcedata/",
                              "Version": f"ExoStudy {version()}, study {study.id}"}]
    return doc


def check_exportable(engine: Engine, db: Session, study_id: int,
                     site: str | None = None) -> None:
    """Raise `NothingToExportError` (saying why) unless the study has a trial with ticks."""
    study = db.get(Study, study_id)
    if study is None:
        raise ValueError(f"study {study_id} does not exist")
    chosen = (Participant.study_id == study_id) & Participant.withdrawn_at.is_(None)
    if site is not None:
        chosen = chosen & (Participant.site == site)
    runs = db.scalars(select(Trial.run_id).join(StudySession,
                                                StudySession.id == Trial.session_id)
                      .join(Participant, Participant.id == StudySession.participant_id)
                      .where(chosen, Trial.run_id.is_not(None)))
    for run_id in runs:
        if run_id is not None and tick_queries.columns(engine, run_id, fields=("t",))["t"].size:
            return
    where = f" at site {site}" if site is not None else ""
    raise NothingToExportError(
        f"study {study_id} has no trial with recorded ticks{where}: a BIDS motion "
        "dataset needs at least one (run a trial first)")


def dataset_files(engine: Engine, db: Session, study_id: int, site: str | None = None,
                  unblind: bool = False, emg_dir: Path | None = None
                  ) -> Iterator[tuple[str, bytes]]:
    """Every file of the study's BIDS dataset as (relative path, content).

    Withdrawn participants are left out, and with `site` everyone of another site (a
    member limited to one site exports only that site). `unblind`: name controllers
    (only the study's owner may). Raises `NothingToExportError` before the first file if
    the study has no trial with ticks. `emg_dir`: the EMG recordings' folder (default:
    the one of the database `engine` is connected to)."""
    check_exportable(engine, db, study_id, site)
    emg = emg_dir if emg_dir is not None else store.engine_emg_folder(engine)
    study = db.get(Study, study_id)
    assert study is not None
    yield "dataset_description.json", _json(_description(study)).encode()
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
        list(bids_dictionary.BIDS_FILES["participants.tsv"][1]),
        [[f"sub-{subs[p.id]}", p.age, p.sex, p.height_m, p.mass_kg]
         for p in participants]).encode()
    yield "participants.json", _json(bids_dictionary.bids_sidecar("participants.tsv")).encode()
    info: dict[str, Any] = study.dataset_info or {}
    for p in participants:
        sessions = list(db.scalars(select(StudySession).where(
            StudySession.participant_id == p.id).order_by(StudySession.started_at,
                                                          StudySession.id)))
        blinded = {c.controller: c.label for c in db.scalars(
            select(ConditionLabel).where(ConditionLabel.participant_id == p.id))}
        seen: dict[str, int] = {}
        for sess in sessions:
            kind = SESSION_KIND.get(sess.kind, label(sess.kind).lower())
            seen[kind] = seen.get(kind, 0) + 1
            yield from _session_files(engine, db, subs[p.id], sess, f"{kind}{seen[kind]}",
                                      blinded, unblind, info, emg)
    yield from _phenotype(db, subs)


def _motion_sidecar(trial: Trial, device: str, t: Any, info: dict[str, Any],
                    unblind: bool, blinded_label: str | None) -> dict[str, Any]:
    """The `*_motion.json` of one trial."""
    duration = float(t[-1] - t[0]) + 1.0 / SAMPLE_RATE_HZ
    about = (f"under the {trial.controller} controller (blinded label "
             f"{blinded_label or 'n/a'})" if unblind else
             f"under the controller the participant knew as {blinded_label or 'n/a'}")
    counts = {f"{kind}ChannelCount": sum(1 for c in CHANNELS if c.type == kind)
              for kind in ("ACCEL", "ANGACCEL", "GYRO", "JNTANG", "LATENCY", "MAGN", "MISC",
                           "ORNT", "POS", "VEL")}
    flags: dict[str, Any] = trial.quality_flags or {}
    faults = {k: v for k, v in flags.items() if v}
    doc: dict[str, Any] = {
        "TaskName": trial.task,
        "TaskDescription": f"{trial.task} with the exoskeleton {about}",
        "SamplingFrequency": SAMPLE_RATE_HZ,
        "SamplingFrequencyEffective": (t.size - 1) / float(t[-1] - t[0])
        if t.size > 1 and t[-1] > t[0] else SAMPLE_RATE_HZ,
        "RecordingDuration": duration,
        "TrackingSystemName": "quasi-passive hip exoskeleton encoders (component x: "
                              "rotation about the medio-lateral axis, flexion positive)",
        "Manufacturer": "ExoStudy",
        "ManufacturersModelName": "quasi-passive hip exoskeleton",
        # The device the ticks came from ("sim": the simulated exoskeleton).
        "DeviceSerialNumber": device,
        "SoftwareVersions": f"ExoStudy {version()}",
        "TrackedPointsCount": 2,
        **counts,
        "MotionChannelCount": len(CHANNELS),
        "MissingValues": "n/a",
        "SubjectArtefactDescription": (
            "device clock faults: " + ", ".join(f"{k} {v}" for k, v in sorted(faults.items()))
            if faults else "none detected (no device time gaps or steps backwards)"),
    }
    for key, field in (("InstitutionName", "institution_name"),
                       ("InstitutionAddress", "institution_address"),
                       ("InstitutionalDepartmentName", "institution_department"),
                       ("Instructions", "instructions")):
        if info.get(field):
            doc[key] = info[field]
    return doc


def _session_files(engine: Engine, db: Session, sub: str, sess: StudySession, ses_label: str,
                   blinded: dict[str, str], unblind: bool, info: dict[str, Any],
                   emg_dir: Path) -> Iterator[tuple[str, bytes]]:
    ses = f"ses-{ses_label}"
    trials = list(db.scalars(select(Trial).where(Trial.session_id == sess.id,
                                                 Trial.run_id.is_not(None))
                             .order_by(Trial.planned_order, Trial.id)))
    counts: dict[tuple[str, str], int] = {}
    scans: list[list[Any]] = []
    emg_recordings = list(db.scalars(select(EmgRecording).where(
        EmgRecording.session_id == sess.id, EmgRecording.status.in_(ANALYSED_STATUSES))
        .order_by(EmgRecording.id)))
    for trial in trials:
        assert trial.run_id is not None
        cols = tick_queries.columns(engine, trial.run_id)
        if cols["t"].size == 0:
            continue
        condition = trial.condition or trial.controller  # e.g. umc+personal
        blinded_label = blinded.get(condition)
        task = label(trial.task)
        acq = label(condition if unblind else blinded_label or "unlabelled")
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
        run = db.get(Run, trial.run_id)
        yield f"{stem}_motion.json", _json(_motion_sidecar(
            trial, run.device_kind if run is not None else "n/a", t, info, unblind,
            blinded_label)).encode()
        started = (trial.started_at.replace(tzinfo=None).isoformat(timespec="seconds")
                   if trial.started_at else None)
        scans.append([f"motion/{stem.rsplit('/', 1)[1]}_motion.tsv", started,
                      *([trial.id, trial.controller] if unblind else []), blinded_label,
                      trial.status, trial.hardware_profile_id])
        ev_rows = _events(db, trial, float(t[0]), cols)
        ev_cols = list(bids_dictionary.BIDS_FILES["*_events.tsv"][1])
        yield f"{folder}{base}_acq-{acq}_run-{k}_events.tsv", _tsv(ev_cols, ev_rows).encode()
        events_doc: dict[str, Any] = bids_dictionary.bids_sidecar("*_events.tsv")
        events_doc["StimulusPresentation"] = {
            "SoftwareName": "ExoStudy", "SoftwareVersion": version(),
            "Code": "no stimuli are presented; events are the experimenter's lifts, the "
                    "exoskeleton's lock commands and states, and markers"}
        yield f"{folder}{base}_acq-{acq}_run-{k}_events.json", _json(events_doc).encode()
        for path, data in _emg_files(db, emg_recordings, trial, f"sub-{sub}/{ses}/emg/",
                                     f"{base}_acq-{acq}_run-{k}", ev_rows, ev_cols,
                                     events_doc, blinded_label, unblind, info, emg_dir):
            if path.endswith("_emg.bdf"):
                scans.append([f"emg/{path.rsplit('/', 1)[1]}", started,
                              *([trial.id, trial.controller] if unblind else []),
                              blinded_label, trial.status, trial.hardware_profile_id])
            yield path, data
    if scans:
        prefix = f"sub-{sub}/{ses}/sub-{sub}_{ses}_scans"
        scan_cols = [c for c in bids_dictionary.BIDS_FILES["*_scans.tsv"][1]
                     if unblind or ("*_scans.tsv", c) not in data_dictionary.BLINDING_KEY]
        yield f"{prefix}.tsv", _tsv(scan_cols, scans).encode()
        yield f"{prefix}.json", _json(bids_dictionary.bids_sidecar("*_scans.tsv", scan_cols)
                                      ).encode()
    for att in db.scalars(select(XdfAttachment).where(XdfAttachment.session_id == sess.id)
                          .order_by(XdfAttachment.id)):
        yield (f"sourcedata/sub-{sub}/{ses}/{att.id}_{label(att.filename.removesuffix('.xdf'))}"
               ".xdf", att.content)


def _emg_files(db: Session, recs: list[EmgRecording], trial: Trial, folder: str, stem: str,
               ev_rows: list[list[Any]], ev_cols: list[str], events_doc: dict[str, Any],
               blinded_label: str | None, unblind: bool, info: dict[str, Any],
               emg_dir: Path) -> Iterator[tuple[str, bytes]]:
    """The trial's EMG (BIDS-EMG) from the first recording covering it, with the motion
    file's events on the EMG file's time axis."""
    rec = next((r for r in recs if any(t["trial_id"] == trial.id for t in r.trials)), None)
    montage = db.get(EmgMontage, rec.montage_id) if rec is not None else None
    if rec is None or montage is None:
        return
    study_id = db.scalar(select(Participant.study_id).join(
        StudySession, StudySession.participant_id == Participant.id)
        .where(StudySession.id == trial.session_id))
    analysis = db.get(EmgAnalysisSettings, study_id) if study_id is not None else None
    processing = (analysis.processing if analysis is not None and analysis.processing
                  else EmgProcessing().to_dict())
    about = (f"{trial.task} under the {trial.controller} controller" if unblind else
             f"{trial.task} under the controller the participant knew as "
             f"{blinded_label or 'n/a'}")
    start = next(float(t["start"]) for t in rec.trials if t["trial_id"] == trial.id)
    parts = dict(emg_bids.trial_files(emg_dir, rec, montage, trial.id, stem,
                                      trial.task, about,
                                      analysis.mains_hz if analysis is not None else 50,
                                      processing, info))
    if not parts:
        return
    shift = float(parts.pop("shift")) - start
    yield f"{folder}{stem}_emg.bdf", parts[f"{stem}_emg.bdf"]
    yield f"{folder}{stem}_emg.json", _json(parts[f"{stem}_emg.json"]).encode()
    cols, rows = parts[f"{stem}_channels.tsv"]
    yield f"{folder}{stem}_channels.tsv", _tsv(cols, rows).encode()
    shifted = [[r[0] - shift, *r[1:]] for r in ev_rows if r[0] - shift >= 0]
    yield f"{folder}{stem}_events.tsv", _tsv(ev_cols, shifted).encode()
    yield f"{folder}{stem}_events.json", _json(events_doc).encode()


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
    # HED joins the annotations of all rows at one onset; a repeated group is an error,
    # so a row identical to one before it at the same onset carries none.
    seen: set[tuple[float, str]] = set()
    for r in rows:
        side = f", Label/{r[3]}-hip" if r[3] in ("left", "right") else ""
        hed = f"({EVENT_HED[r[2]]}{side})"
        r.append("n/a" if (r[0], hed) in seen else hed)
        seen.add((r[0], hed))
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
        fixed = list(bids_dictionary.BIDS_FILES["phenotype/*.tsv"][1])
        yield f"phenotype/{name}.tsv", _tsv(
            [*fixed, *items],
            [[f"sub-{subs[r.participant_id]}", r.condition_label, r.instrument_version,
              r.score, *[r.answers.get(i) for i in items]] for r in rs]).encode()
        doc: dict[str, Any] = {
            "MeasurementToolMetadata": {"Description": f"questionnaire {key}"},
            **bids_dictionary.bids_sidecar("phenotype/*.tsv"),
        }
        for i in items:
            doc[i] = {"Description": f"answer to item {i}"}
        yield f"phenotype/{name}.json", _json(doc).encode()
