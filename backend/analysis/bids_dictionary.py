"""The BIDS export's tabular files described: their sidecars (`*.json` next to each
`*.tsv`) and the README's BIDS section are generated from these entries, one definition,
so the dictionary and the sidecars cannot say different things."""

from __future__ import annotations

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
