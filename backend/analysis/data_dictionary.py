"""Meaning and unit of every column ExoStudy exports. A test checks that every exported
column is described here, so a new column cannot leave the dictionary silently."""

from __future__ import annotations

from controller.tick_record import TICK_FIELD_DOCS

# (unit, meaning); "" unit for identifiers, text and categories.
_COMMON: dict[str, tuple[str, str]] = {
    "id": ("", "row identifier, unique within the file"),
    "created_at": ("ISO 8601 UTC", "when the row was created"),
    "created_by": ("", "experimenter account id that created it (users are not exported)"),
    "notes": ("", "free text from the experimenter"),
    "status": ("", "state of the row (see the file's description)"),
    "name": ("", "name given by the experimenter"),
    "hardware_profile_id": ("", "hardware profile in effect (the last completed hardware "
                            "bring-up: encoder zeros and directions, cam offset, firmware "
                            "version, link key id; docs/hardware-bringup.md); empty: none"),
}

TABLES: dict[str, tuple[str, dict[str, tuple[str, str]]]] = {
    "participants": ("One row per participant, under a pseudonymous code.", {
        "study_id": ("", "study id"),
        "code": ("", "pseudonymous participant code"),
        "age": ("years", "age at enrolment"),
        "sex": ("", "sex as recorded by the experimenter"),
        "height_m": ("m", "body height"),
        "mass_kg": ("kg", "body mass"),
        "consent_date": ("ISO 8601 date", "date informed consent was given"),
        "site": ("", "site that recruited the participant (empty: single-site study)"),
        "consent_version": ("", "version of the study's consent document agreed to"),
        "withdrawn_at": ("ISO 8601 UTC", "when the participant withdrew (kept, excluded "
                         "from results); empty otherwise"),
    }),
    "study_sessions": ("One row per visit: data collection (demonstrations) or evaluation.", {
        "participant_id": ("", "participant id"),
        "kind": ("", "data_collection, evaluation or long_use (use outside a trial plan)"),
        "precompression_pct": ("% of 22 mm", "spring precompression of the exoskeleton"),
        "started_at": ("ISO 8601 UTC", "start of the session"),
    }),
    "condition_labels": ("The blinding key: which controller each label stood for.", {
        "participant_id": ("", "participant id"),
        "label": ("", "label the participant saw (A, B, C)"),
        "controller": ("", "controller behind the label: umc, eumc or pec; the blinding "
                       "key, so filled in only in exports made by the study's owner (empty "
                       "in an experimenter's de-identified export)"),
    }),
    "recordings": ("Continuous 100 Hz recordings of demonstrations (no locks; status "
                   "recording, stopped or interrupted); ticks in ticks/recording-<id>.csv.", {
        "session_id": ("", "session id"),
        "run_id": ("", "worker run that produced the ticks"),
        "label": ("", "label given when recording"),
        "started_at": ("ISO 8601 UTC", "start"),
        "ended_at": ("ISO 8601 UTC", "end"),
        "first_tick_id": ("", "first stored tick of the recording"),
        "last_tick_id": ("", "last stored tick of the recording"),
    }),
    "lift_segments": ("Lifts in recordings: sample indices from the recording's first tick "
                      "(row 0 of its ticks file).", {
        "recording_id": ("", "recording id"),
        "start": ("sample", "motion onset"),
        "peak": ("sample", "peak hip flexion"),
        "end": ("sample", "return to rest"),
        "label": ("", "squat, stoop_left, stoop_right, other or unlabelled"),
        "source": ("", "auto (segmentation) or edited (by the experimenter)"),
        "updated_at": ("ISO 8601 UTC", "last change"),
    }),
    "trial_segments": ("Lifts in trials marked by the experimenter (the ground truth of "
                       "trials without simulation labels): sample indices from the trial's "
                       "first tick (row 0 of ticks/trial-<id>.csv).", {
        "trial_id": ("", "trial id"),
        "start": ("sample", "motion onset"),
        "peak": ("sample", "peak hip flexion"),
        "end": ("sample", "return to rest"),
        "label": ("", "squat, stoop_left, stoop_right, other or unlabelled"),
        "source": ("", "auto (segmentation) or edited (by the experimenter)"),
        "updated_at": ("ISO 8601 UTC", "last change"),
    }),
    "model_sets": ("Fitted motion model sets; the models are in model_sets/<id>.json.", {
        "study_id": ("", "study id"),
        "params": ("JSON", "fit parameters: latent dimension, explained variance, counts"),
        "segment_ids": ("JSON list", "segments the models were fitted from"),
        "error": ("", "why fitting failed, if it did"),
        "kind": ("", "population (a study's demonstrations) or personal (one participant's)"),
        "method": ("", "ppca (fitted from the demonstrations alone) or map (the population "
                   "set base_model_set_id adapted to the participant's demonstrations)"),
        "participant_id": ("", "wearer of a personal model set; empty for a population set"),
        "base_model_set_id": ("", "population model set a personal set adapts or was "
                              "planned beside"),
    }),
    "prior_sets": ("Each participant's versioned priors, learned from use and kept inside "
                   "the safety bound of a utility set; documents in prior_sets/<id>.json.", {
        "study_id": ("", "study id"),
        "participant_id": ("", "participant id"),
        "version": ("", "1, 2, ... per participant, in the order made"),
        "method": ("", "dirichlet (confirmed motions), label-shift-em (unconfirmed use), "
                   "equal or import"),
        "utility_set_id": ("", "utility set whose safety bound the values satisfy"),
        "previous_id": ("", "prior set whose counts this one continued"),
        "params": ("JSON", "learning parameters: floor, pseudo-count, forgetting, motions"),
        "error": ("", "why learning failed, if it did"),
    }),
    "utility_sets": ("Utility tables per precompression; the tables are in "
                     "utility_sets/<id>.json.", {
        "study_id": ("", "study id"),
        "precompression_pct": ("% of 22 mm", "actuator setting the utilities are for"),
        "human_source": ("", "human motion dataset used: simulated:<version> or imported:<file>"),
        "error": ("", "why computing failed, if it did"),
    }),
    "trials": ("Evaluation trials (status planned, running, completed, aborted or "
               "interrupted); ticks in ticks/trial-<id>.csv.", {
        "session_id": ("", "session id"),
        "controller": ("", "umc, eumc or pec"),
        "task": ("", "task performed (script name in simulation)"),
        "planned_order": ("", "position in the counterbalanced plan, from 0"),
        "model_set_id": ("", "model set used (UMC, E-UMC)"),
        "utility_set_id": ("", "utility set used (UMC, E-UMC)"),
        "run_id": ("", "worker run that produced the ticks"),
        "config_snapshot": ("JSON", "the exact controller configuration the trial ran with "
                            "(settings with the priors, model set with a personal set's "
                            "provenance, prior set, condition)"),
        "condition": ("", "blinding key of the condition, e.g. umc+personal; empty: the "
                      "controller's name (population models, equal priors)"),
        "models": ("", "population or personal models"),
        "prior_set_id": ("", "prior set the condition ran with; empty: equal priors"),
        "demonstrations": ("JSON", "a demonstration block's demonstrations asked for, per "
                           "motion; empty for other trials"),
        "started_at": ("ISO 8601 UTC", "start"),
        "ended_at": ("ISO 8601 UTC", "end"),
        "end_reason": ("", "reason given when it ended, or why it was interrupted (its "
                       "worker or the server stopped)"),
        "tick_count": ("", "ticks stored for the trial when it ended"),
        "quality_flags": ("JSON", "device clock faults in the ticks: time_gaps (count), "
                          "missing_s, largest_gap_s, time_backwards (count), "
                          "largest_backstep_s; {} when none"),
    }),
    "lock_events": ("Lock commands and mechanism changes per trial, derived from the ticks.", {
        "trial_id": ("", "trial id"),
        "t": ("s", "device time of the event"),
        "side": ("", "left or right"),
        "kind": ("", "command_on, command_off, engaged or released"),
        "torque_peak": ("Nm", "peak exoskeleton torque of the engagement (engaged rows)"),
    }),
    "questionnaire_responses": ("Questionnaire answers with their scores.", {
        "participant_id": ("", "participant id"),
        "link_id": ("", "participant link the answers came through"),
        "instrument_id": ("", "instrument id"),
        "instrument_key": ("", "instrument key, e.g. sus, eus"),
        "instrument_version": ("", "instrument version the score was computed with"),
        "condition_label": ("", "blinded controller label the answers are about"),
        "answers": ("JSON", "item id -> answer on the instrument's scale"),
        "link_form": ("", "position of the form in its link's list (from 0); empty when "
                      "not entered through a link"),
        "score": ("instrument's range", "total score (SUS 0-100, EUS 0-10)"),
        "subscale_scores": ("JSON", "subscale -> score"),
        "submitted_at": ("ISO 8601 UTC", "when submitted"),
    }),
    "preferences": ("Stated preference after the controllers.", {
        "participant_id": ("", "participant id"),
        "link_id": ("", "participant link it came through"),
        "choice": ("", "blinded label preferred, or no_preference"),
        "submitted_at": ("ISO 8601 UTC", "when submitted"),
    }),
    "markers": ("Event markers: from the console, from other software's LSL marker "
                "streams, and the system's trial start and stop.", {
        "session_id": ("", "session id"),
        "trial_id": ("", "trial whose run produced the marker's tick; empty between trials"),
        "run_id": ("", "worker run of the marker's tick"),
        "t": ("s", "device time of the tick the marker is placed at"),
        "lsl_time": ("s", "the same instant on the Lab Streaming Layer clock"),
        "label": ("", "marker label (console button, LSL sample text, trial_start/stop); "
                  "the de-identified export keeps the system's labels and the study's "
                  "marker buttons and replaces any other text with \"other\""),
        "note": ("", "free text typed with the marker"),
        "source": ("", "console, lsl or system"),
        "stream_id": ("", "the LSL marker stream subscription it came from"),
    }),
    "xdf_attachments": ("LabRecorder XDF files attached to a session (the files "
                        "themselves are in the BIDS export's sourcedata).", {
        "session_id": ("", "session id"),
        "filename": ("", "file name as uploaded"),
        "size_bytes": ("bytes", "file size"),
        "sha256": ("", "SHA-256 of the file"),
        "streams": ("JSON", "each stream: name, type, channels, samples, LSL time span, "
                    "trials covered, clock offset of ExoStudy's own stream (ms)"),
    }),
}

TICK_FILE = ("One row per 10 ms control tick. Empty cells: not computed at that tick "
             "(for example DTW outputs when a 10 Hz controller did not run).")


def describe(table: str, column: str) -> tuple[str, str]:
    """(unit, meaning) of an exported column; KeyError if undocumented."""
    if table == "ticks":
        return TICK_FIELD_DOCS[column]
    cols = TABLES[table][1]
    if column in cols:
        return cols[column]
    return _COMMON[column]


def markdown() -> str:
    """The dictionary as a README for the export."""
    lines = ["# ExoStudy export: data dictionary", "",
             "Every CSV file has a header row. Angles are in radians, torques in Nm, times "
             "in seconds unless stated. Units below.", ""]
    for table, (about, _cols) in TABLES.items():
        lines += [f"## {table}.csv", "", about, "", "| column | unit | meaning |",
                  "|---|---|---|"]
        for col in _columns_of(table):
            unit, meaning = describe(table, col)
            lines.append(f"| {col} | {unit} | {meaning} |")
        lines.append("")
    lines += ["## ticks/trial-<id>.csv, ticks/recording-<id>.csv", "", TICK_FILE, "",
              "| column | unit | meaning |", "|---|---|---|"]
    from controller.tick_record import TickRecord

    for col in TickRecord.field_names():
        unit, meaning = TICK_FIELD_DOCS[col]
        lines.append(f"| {col} | {unit} | {meaning} |")
    lines += ["", *bids_markdown(), "", *exports_markdown()]
    return "\n".join(lines) + "\n"


def _columns_of(table: str) -> list[str]:
    from backend.analysis.export import EXPORTED_COLUMNS

    return EXPORTED_COLUMNS[table]


# BIDS export ---------------------------------------------------------------------------
# The BIDS export's tabular files and their sidecars (`*.json` next to each `*.tsv`) are
# generated from these entries, and so is the section of the README above: one
# definition, so the dictionary and the sidecars cannot say different things.

#: file -> (what it holds, column -> (BIDS unit or "", meaning)).
BIDS_FILES: dict[str, tuple[str, dict[str, tuple[str, str]]]] = {
    "participants.tsv": ("One row per participant (withdrawn ones left out), de-identified "
                         "fields only.", {
        "participant_id": ("", "pseudonymous participant code"),
        "age": ("year", "age at enrolment"),
        "sex": ("", "sex as recorded by the experimenter"),
        "height": ("m", "body height"),
        "weight": ("kg", "body mass"),
    }),
    "*_scans.tsv": ("One row per motion file of a session.", {
        "filename": ("", "the trial's motion file"),
        "acq_time": ("", "when the trial started (UTC)"),
        "trial_id": ("", "ExoStudy's trial id (only in an owner's export: ExoStudy shows "
                     "each trial's controller, so the id would unblind the label)"),
        "controller": ("", "the exoskeleton controller of the trial: umc, eumc or pec (only "
                       "in an owner's export: with blinded_label it is the blinding key)"),
        "blinded_label": ("", "the label the participant knew the controller by"),
        "outcome": ("", "completed or aborted"),
        "hardware_profile_id": ("", "hardware profile in effect during the trial (as in "
                                "trials.csv); n/a: none"),
    }),
    "*_events.tsv": ("Events of one motion file: lifts, lock commands and mechanism "
                     "edges, markers.", {
        "onset": ("s", "seconds from the first sample of the motion file"),
        "duration": ("s", "lift duration; 0 for instantaneous events"),
        "trial_type": ("", "what happened"),
        "side": ("", "left or right hip; n/a for both"),
        "value": ("", "lift label, peak torque (N.m) of an engagement, or the marker's "
                  "label and note"),
        "source": ("", "where the event comes from: segment (the experimenter's lifts), "
                   "lock_events (derived from the ticks), console, lsl or system"),
        "HED": ("", "the event in Hierarchical Event Descriptors (HED 8.3.0): its kind and "
                "side; n/a for a repeat of the row before it at the same onset"),
    }),
    "phenotype/*.tsv": ("One file per questionnaire: one row per response, then one "
                        "column per item (`answer to item <id>`).", {
        "participant_id": ("", "pseudonymous participant code"),
        "condition_label": ("", "blinded condition the answers are about"),
        "instrument_version": ("", "version of the questionnaire definition"),
        "score": ("", "total score computed at submission (SUS 0-100, EUS 0-10)"),
    }),
}

#: Levels of categorical BIDS columns, for the sidecars.
BIDS_LEVELS: dict[tuple[str, str], dict[str, str]] = {
    ("*_events.tsv", "trial_type"): {
        "lift": "a lift marked by the experimenter",
        "command_on": "solenoid command on",
        "command_off": "solenoid command off",
        "engaged": "ratchet engaged",
        "released": "ratchet released",
        "marker": "an event marker (console, LSL or system)",
    },
    ("*_scans.tsv", "outcome"): {"completed": "the trial ran to its end",
                                 "aborted": "the experimenter ended it early"},
}

#: Columns that together with a blinded label unblind a condition: written only in an
#: export made by the study's owner (empty, or left out, in anyone else's).
BLINDING_KEY: frozenset[tuple[str, str]] = frozenset({
    ("condition_labels.csv", "controller"), ("*_scans.tsv", "controller"),
    ("*_scans.tsv", "trial_id")})


def bids_sidecar(file: str, columns: list[str] | None = None) -> dict[str, dict[str, object]]:
    """The JSON sidecar describing `file`'s columns (only `columns`, if given)."""
    cols = BIDS_FILES[file][1]
    out: dict[str, dict[str, object]] = {}
    for name in columns if columns is not None else list(cols):
        if name == "HED":  # HED's own column: a sidecar may not describe it
            continue
        unit, meaning = cols[name]
        entry: dict[str, object] = {"Description": meaning}
        if unit:
            entry["Units"] = unit
        levels = BIDS_LEVELS.get((file, name))
        if levels:
            entry["Levels"] = dict(levels)
        out[name] = entry
    return out


def bids_markdown() -> list[str]:
    """The BIDS export's tabular files, as README lines."""
    lines = ["## BIDS export (export.bids.zip)", "",
             "Motion files have no header (`*_channels.tsv` names their columns); the "
             "other tables are described below and, in the dataset itself, by the JSON "
             "sidecar next to each file.", ""]
    for file, (about, cols) in BIDS_FILES.items():
        lines += [f"### {file}", "", about, "", "| column | unit | meaning |", "|---|---|---|"]
        lines += [f"| {c} | {u} | {m} |" for c, (u, m) in cols.items()]
        lines.append("")
    return lines


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
