"""Meaning and unit of every column ExoStudy exports, generated from the SQLAlchemy models
plus one table of descriptions (`COLUMNS`): the export's tables and their columns are the
models' own (`exported_columns`), so a column added to a model appears in the export,
and a test fails until it has a description here (`undocumented`)."""

from __future__ import annotations

from sqlalchemy import MetaData

from backend.analysis.bids_dictionary import bids_markdown
from backend.db.tables import Base
from controller.tick_record import TICK_FIELD_DOCS, TickRecord

#: Columns left out of the CSVs: large documents (written as JSON files instead), and
#: the de-identified export's stored date shifts (which would undo it).
OMITTED = frozenset({"document", "human_data", "content", "date_shift_days"})
#: The tables a study export writes, in order, one CSV each.
EXPORTED_TABLES = ("participants", "study_sessions", "condition_labels", "recordings",
                   "lift_segments", "model_sets", "utility_sets", "prior_sets", "trials",
                   "trial_segments", "lock_events", "questionnaire_responses", "preferences",
                   "markers", "xdf_attachments")
#: The two segment tables share their segment columns (`backend.db.segments`) and so
#: their descriptions (`segments.<column>` below).
SEGMENT_TABLES = frozenset({"lift_segments", "trial_segments"})


def exported_columns(metadata: MetaData = Base.metadata) -> dict[str, list[str]]:
    """Each exported table's columns, as the models define them, minus `OMITTED`."""
    return {name: [c.name for c in metadata.tables[name].columns if c.name not in OMITTED]
            for name in EXPORTED_TABLES}


EXPORTED_COLUMNS: dict[str, list[str]] = exported_columns()

#: What each exported file holds.
TABLE_ABOUT: dict[str, str] = {
    "participants": "One row per participant, under a pseudonymous code.",
    "study_sessions": "One row per visit: data collection (demonstrations) or evaluation.",
    "condition_labels": "The blinding key: which controller each label stood for.",
    "recordings": ("Continuous 100 Hz recordings of demonstrations (no locks; status recording, "
                   "stopped or interrupted); ticks in ticks/recording-<id>.csv."),
    "lift_segments": ("Lifts in recordings: sample indices from the recording's first tick (row "
                      "0 of its ticks file)."),
    "trial_segments": ("Lifts in trials marked by the experimenter (the ground truth of trials "
                       "without simulation labels): sample indices from the trial's first tick "
                       "(row 0 of ticks/trial-<id>.csv)."),
    "model_sets": "Fitted motion model sets; the models are in model_sets/<id>.json.",
    "prior_sets": ("Each participant's versioned priors, learned from use and kept inside the "
                   "safety bound of a utility set; documents in prior_sets/<id>.json."),
    "utility_sets": "Utility tables per precompression; the tables are in utility_sets/<id>.json.",
    "trials": ("Evaluation trials (status planned, running, completed, aborted or interrupted); "
               "ticks in ticks/trial-<id>.csv."),
    "lock_events": "Lock commands and mechanism changes per trial, derived from the ticks.",
    "questionnaire_responses": "Questionnaire answers with their scores.",
    "preferences": "Stated preference after the controllers.",
    "markers": ("Event markers: from the console, from other software's LSL marker streams, and "
                "the system's trial start and stop."),
    "xdf_attachments": ("LabRecorder XDF files attached to a session (the files themselves are "
                        "in the BIDS export's sourcedata)."),
}

#: (unit, meaning) per `table.column` ("" unit for identifiers, text and categories);
#: `*.column` for a column every table that has it shares.
COLUMNS: dict[str, tuple[str, str]] = {
    # Columns of every table that has them.
    "*.id": ("", "row identifier, unique within the file"),
    "*.created_at": ("ISO 8601 UTC", "when the row was created"),
    "*.created_by": ("", "experimenter account id that created it (users are not exported)"),
    "*.notes": ("", "free text from the experimenter"),
    "*.status": ("", "state of the row (see the file's description)"),
    "*.name": ("", "name given by the experimenter"),
    "*.hardware_profile_id": ("", "hardware profile in effect (the last completed hardware "
                                  "bring-up: encoder zeros and directions, cam offset, firmware "
                                  "version, link key id; docs/hardware-bringup.md); empty: none"),
    # The columns both segment tables share (`backend.db.segments.SegmentColumns`).
    "segments.start": ("sample", "motion onset"),
    "segments.peak": ("sample", "peak hip flexion"),
    "segments.end": ("sample", "return to rest"),
    "segments.label": ("", "squat, stoop_left, stoop_right, other or unlabelled"),
    "segments.source": ("", "auto (segmentation) or edited (by the experimenter)"),
    "segments.updated_at": ("ISO 8601 UTC", "last change"),
    # participants
    "participants.study_id": ("", "study id"),
    "participants.code": ("", "pseudonymous participant code"),
    "participants.age": ("years", "age at enrolment"),
    "participants.sex": ("", "sex as recorded by the experimenter"),
    "participants.height_m": ("m", "body height"),
    "participants.mass_kg": ("kg", "body mass"),
    "participants.consent_date": ("ISO 8601 date", "date informed consent was given"),
    "participants.site": ("", "site that recruited the participant (empty: single-site study)"),
    "participants.consent_version": ("", "version of the study's consent document agreed to"),
    "participants.withdrawn_at": ("ISO 8601 UTC", "when the participant withdrew (kept, excluded "
                                                  "from results); empty otherwise"),
    # study_sessions
    "study_sessions.participant_id": ("", "participant id"),
    "study_sessions.kind": ("", "data_collection, evaluation or long_use (use outside a trial "
                                "plan)"),
    "study_sessions.precompression_pct": ("% of 22 mm", "spring precompression of the "
                                                        "exoskeleton"),
    "study_sessions.started_at": ("ISO 8601 UTC", "start of the session"),
    # condition_labels
    "condition_labels.participant_id": ("", "participant id"),
    "condition_labels.label": ("", "label the participant saw (A, B, C)"),
    "condition_labels.controller": ("", "controller behind the label: umc, eumc or pec; the "
                                        "blinding key, so filled in only in exports made by the "
                                        "study's owner (empty in an experimenter's "
                                        "de-identified export)"),
    # recordings
    "recordings.session_id": ("", "session id"),
    "recordings.run_id": ("", "worker run that produced the ticks"),
    "recordings.label": ("", "label given when recording"),
    "recordings.started_at": ("ISO 8601 UTC", "start"),
    "recordings.ended_at": ("ISO 8601 UTC", "end"),
    "recordings.first_tick_id": ("", "first stored tick of the recording"),
    "recordings.last_tick_id": ("", "last stored tick of the recording"),
    # lift_segments
    "lift_segments.recording_id": ("", "recording id"),
    # trial_segments
    "trial_segments.trial_id": ("", "trial id"),
    # model_sets
    "model_sets.study_id": ("", "study id"),
    "model_sets.params": ("JSON", "fit parameters: latent dimension, explained variance, counts"),
    "model_sets.segment_ids": ("JSON list", "segments the models were fitted from"),
    "model_sets.error": ("", "why fitting failed, if it did"),
    "model_sets.kind": ("", "population (a study's demonstrations) or personal (one "
                            "participant's)"),
    "model_sets.method": ("", "ppca (fitted from the demonstrations alone) or map (the "
                              "population set base_model_set_id adapted to the participant's "
                              "demonstrations)"),
    "model_sets.participant_id": ("", "wearer of a personal model set; empty for a population "
                                      "set"),
    "model_sets.base_model_set_id": ("", "population model set a personal set adapts or was "
                                         "planned beside"),
    # prior_sets
    "prior_sets.study_id": ("", "study id"),
    "prior_sets.participant_id": ("", "participant id"),
    "prior_sets.version": ("", "1, 2, ... per participant, in the order made"),
    "prior_sets.method": ("", "dirichlet (confirmed motions), label-shift-em (unconfirmed use), "
                              "equal or import"),
    "prior_sets.utility_set_id": ("", "utility set whose safety bound the values satisfy"),
    "prior_sets.previous_id": ("", "prior set whose counts this one continued"),
    "prior_sets.params": ("JSON", "learning parameters: floor, pseudo-count, forgetting, motions"),
    "prior_sets.error": ("", "why learning failed, if it did"),
    # utility_sets
    "utility_sets.study_id": ("", "study id"),
    "utility_sets.precompression_pct": ("% of 22 mm", "actuator setting the utilities are for"),
    "utility_sets.human_source": ("", "human motion dataset used: simulated:<version> or "
                                      "imported:<file>"),
    "utility_sets.error": ("", "why computing failed, if it did"),
    # trials
    "trials.session_id": ("", "session id"),
    "trials.controller": ("", "umc, eumc or pec"),
    "trials.task": ("", "task performed (script name in simulation)"),
    "trials.planned_order": ("", "position in the counterbalanced plan, from 0"),
    "trials.model_set_id": ("", "model set used (UMC, E-UMC)"),
    "trials.utility_set_id": ("", "utility set used (UMC, E-UMC)"),
    "trials.run_id": ("", "worker run that produced the ticks"),
    "trials.config_snapshot": ("JSON", "the exact controller configuration the trial ran with "
                                       "(settings with the priors, model set with a personal "
                                       "set's provenance, prior set, condition)"),
    "trials.condition": ("", "blinding key of the condition, e.g. umc+personal; empty: the "
                             "controller's name (population models, equal priors)"),
    "trials.models": ("", "population or personal models"),
    "trials.prior_set_id": ("", "prior set the condition ran with; empty: equal priors"),
    "trials.demonstrations": ("JSON", "a demonstration block's demonstrations asked for, per "
                                      "motion; empty for other trials"),
    "trials.started_at": ("ISO 8601 UTC", "start"),
    "trials.ended_at": ("ISO 8601 UTC", "end"),
    "trials.end_reason": ("", "reason given when it ended, or why it was interrupted (its worker "
                              "or the server stopped)"),
    "trials.tick_count": ("", "ticks stored for the trial when it ended"),
    "trials.quality_flags": ("JSON", "device clock faults in the ticks: time_gaps (count), "
                                     "missing_s, largest_gap_s, time_backwards (count), "
                                     "largest_backstep_s; {} when none"),
    # lock_events
    "lock_events.trial_id": ("", "trial id"),
    "lock_events.t": ("s", "device time of the event"),
    "lock_events.side": ("", "left or right"),
    "lock_events.kind": ("", "command_on, command_off, engaged or released"),
    "lock_events.torque_peak": ("Nm", "peak exoskeleton torque of the engagement (engaged rows)"),
    # questionnaire_responses
    "questionnaire_responses.participant_id": ("", "participant id"),
    "questionnaire_responses.link_id": ("", "participant link the answers came through"),
    "questionnaire_responses.instrument_id": ("", "instrument id"),
    "questionnaire_responses.instrument_key": ("", "instrument key, e.g. sus, eus"),
    "questionnaire_responses.instrument_version": ("", "instrument version the score was "
                                                       "computed with"),
    "questionnaire_responses.condition_label": ("", "blinded controller label the answers are "
                                                    "about"),
    "questionnaire_responses.answers": ("JSON", "item id -> answer on the instrument's scale"),
    "questionnaire_responses.link_form": ("", "position of the form in its link's list (from 0); "
                                              "empty when not entered through a link"),
    "questionnaire_responses.score": ("instrument's range", "total score (SUS 0-100, EUS 0-10)"),
    "questionnaire_responses.subscale_scores": ("JSON", "subscale -> score"),
    "questionnaire_responses.submitted_at": ("ISO 8601 UTC", "when submitted"),
    # preferences
    "preferences.participant_id": ("", "participant id"),
    "preferences.link_id": ("", "participant link it came through"),
    "preferences.choice": ("", "blinded label preferred, or no_preference"),
    "preferences.submitted_at": ("ISO 8601 UTC", "when submitted"),
    # markers
    "markers.session_id": ("", "session id"),
    "markers.trial_id": ("", "trial whose run produced the marker's tick; empty between trials"),
    "markers.run_id": ("", "worker run of the marker's tick"),
    "markers.t": ("s", "device time of the tick the marker is placed at"),
    "markers.lsl_time": ("s", "the same instant on the Lab Streaming Layer clock"),
    "markers.label": ("", "marker label (console button, LSL sample text, trial_start/stop); the "
                          "de-identified export keeps the system's labels and the study's "
                          "marker buttons and replaces any other text with \"other\""),
    "markers.note": ("", "free text typed with the marker"),
    "markers.source": ("", "console, lsl or system"),
    "markers.stream_id": ("", "the LSL marker stream subscription it came from"),
    # xdf_attachments
    "xdf_attachments.session_id": ("", "session id"),
    "xdf_attachments.filename": ("", "file name as uploaded"),
    "xdf_attachments.size_bytes": ("bytes", "file size"),
    "xdf_attachments.sha256": ("", "SHA-256 of the file"),
    "xdf_attachments.streams": ("JSON", "each stream: name, type, channels, samples, LSL time "
                                        "span, trials covered, clock offset of ExoStudy's own "
                                        "stream (ms)"),
}


TICK_FILE = ("One row per 10 ms control tick. Empty cells: not computed at that tick "
             "(for example DTW outputs when a 10 Hz controller did not run).")


def describe(table: str, column: str) -> tuple[str, str]:
    """(unit, meaning) of an exported column: `table.column`, else the segment tables'
    shared `segments.column`, else the common `*.column`; KeyError if undocumented."""
    if table == "ticks":
        return TICK_FIELD_DOCS[column]
    for key in (f"{table}.{column}",
                *([f"segments.{column}"] if table in SEGMENT_TABLES else []), f"*.{column}"):
        if key in COLUMNS:
            return COLUMNS[key]
    raise KeyError(f"{table}.{column}: no description in data_dictionary.COLUMNS")


def undocumented(metadata: MetaData = Base.metadata) -> list[str]:
    """Exported columns (`table.column`) with no description, and tables with no
    `TABLE_ABOUT`; empty when the dictionary is complete."""
    missing = [t for t in EXPORTED_TABLES if t not in TABLE_ABOUT]
    for table, cols in exported_columns(metadata).items():
        for col in cols:
            try:
                describe(table, col)
            except KeyError:
                missing.append(f"{table}.{col}")
    return missing


def markdown() -> str:
    """The dictionary as a README for the export."""
    lines = ["# ExoStudy export: data dictionary", "",
             "Every CSV file has a header row. Angles are in radians, torques in Nm, times "
             "in seconds unless stated. Units below.", ""]
    for table in EXPORTED_TABLES:
        lines += [f"## {table}.csv", "", TABLE_ABOUT[table], "", "| column | unit | meaning |",
                  "|---|---|---|"]
        for col in EXPORTED_COLUMNS[table]:
            unit, meaning = describe(table, col)
            lines.append(f"| {col} | {unit} | {meaning} |")
        lines.append("")
    lines += ["## ticks/trial-<id>.csv, ticks/recording-<id>.csv", "", TICK_FILE, "",
              "| column | unit | meaning |", "|---|---|---|"]
    for col in TickRecord.field_names():
        unit, meaning = TICK_FIELD_DOCS[col]
        lines.append(f"| {col} | {unit} | {meaning} |")
    lines += ["", *bids_markdown(), "", *exports_markdown()]
    return "\n".join(lines) + "\n"


#: Columns that together with a blinded label unblind a condition: written only in an
#: export made by the study's owner (empty, or left out, in anyone else's).
BLINDING_KEY: frozenset[tuple[str, str]] = frozenset({
    ("condition_labels.csv", "controller"), ("*_scans.tsv", "controller"),
    ("*_scans.tsv", "trial_id")})


#: Which export holds what, and who may download it.
EXPORTS: tuple[tuple[str, str, str], ...] = (
    ("export.zip", "owner",
     "every table above with the study's own codes, dates and free text, the blinding "
     "key (condition_labels.csv `controller`), every trial's and recording's ticks"),
    ("export-deidentified.zip", "experimenter or owner",
     "the same files; participants re-coded, free text and account ids removed, marker "
     "labels other than the system's and the study's marker buttons replaced by "
     "\"other\", ages above 89 as 90, dates moved back by each participant's own stored "
     "shift (the same at every download); the blinding key only in an owner's download"),
    ("export.bids.zip", "experimenter or owner",
     "the evaluation trials as BIDS motion files with events, participants' de-identified "
     "fields, questionnaires as phenotype files, attached XDF files as source data; "
     "motion files are named by blinded label (`acq-A`) and `*_scans.tsv` has neither "
     "`controller` nor `trial_id`, except in an owner's download (`acq-umc`, both)"),
)


def exports_markdown() -> list[str]:
    """The table of exports, as README lines."""
    lines = ["## Which export holds what", "", "| export | who may download it | holds |",
             "|---|---|---|"]
    lines += [f"| {name} | {who} | {what} |" for name, who, what in EXPORTS]
    return lines
