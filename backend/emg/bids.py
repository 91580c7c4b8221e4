"""BIDS-EMG (BIDS 1.11): a trial's EMG as a BDF file with its sidecars.

For each trial a recording covers, the export writes in `emg/` beside `motion/`:

    <base>_acq-<controller>_run-<k>_emg.bdf       the trial's span, 24-bit BDF (edfio)
    <base>_acq-<controller>_run-<k>_emg.json      EMGPlacementScheme, EMGReference,
                                                   SamplingFrequency, PowerLineFrequency,
                                                   SoftwareFilters, TaskName, ...
    <base>_acq-<controller>_run-<k>_channels.tsv  muscle, side, placement, distance
    <base>_acq-<controller>_run-<k>_events.tsv/.json  the motion file's events, on the
                                                   EMG file's time axis

The span is the trial's (start to stop marker) cut from the recording, so its first
sample is the trial's start when the recording covers it; the events are the motion
events shifted by any difference. No `_electrodes.tsv`: a montage states placements in
words (SENIAM), not coordinates, and BIDS' electrodes file needs coordinates; the
placement is in `_channels.tsv` (`placement_description`). Samples that are NaN or
infinite (BDF cannot hold them) are written as 0 and the channel's `status` is `bad`
with the count. The file is raw (`SoftwareFilters` "n/a"); every parameter of the
study's processing chain is stated in `TaskDescription`.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from backend.db.emg import EmgMontage, EmgRecording
from backend.emg import store

#: BDF data record lengths tried in order (the first giving a whole number of samples
#: per record at the rate wins): files hold whole records, so the last is padded with
#: zeros after `RecordingDuration` (said in `_emg.json`). 2048 Hz (BioSemi) needs 1 s.
RECORD_CHOICES_S = (0.1, *range(1, 101))
#: A BDF header holds a record's sample count in 8 characters.
MAX_SAMPLES_PER_RECORD = 99_999_999
#: BDF signal labels are 16 characters.
LABEL_CHARS = 16
#: 24-bit BDF digital range.
BDF_DIGITAL = (-8388608, 8388607)


def _physical_range(x: NDArray[np.float64]) -> tuple[float, float]:
    """A symmetric range in microvolts holding every sample (at least 1 uV)."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    peak = max(1.0, math.ceil(peak * 1.01))
    return -peak, peak


def record_duration(fs: float) -> float:
    """The shortest record length of `RECORD_CHOICES_S` holding whole samples at `fs`;
    ValueError naming the rate when none does (import refuses such a rate, so every
    stored recording can be exported)."""
    if math.isfinite(fs) and fs > 0:
        for d in RECORD_CHOICES_S:
            n = fs * d
            if 1 <= round(n) <= MAX_SAMPLES_PER_RECORD and abs(n - round(n)) <= 1e-9 * n:
                return float(d)
    raise ValueError(f"a sampling rate of {fs!r} Hz gives no whole number of samples in a "
                     f"BDF data record of {RECORD_CHOICES_S[0]} s or 1 to "
                     f"{RECORD_CHOICES_S[-1]} s, so it cannot be exported as BIDS-EMG")


def bdf_labels(labels: list[str]) -> list[str]:
    """Labels unique within BDF's 16 characters. A label that fits and is unique stays;
    one that is longer, or whose first 16 characters another label shares, becomes its
    first characters + "~" + its channel number (1-based, montage order), e.g.
    `erector_spinae_~3`. The full label is in `_channels.tsv`'s `description`."""
    cut = [lb[:LABEL_CHARS] for lb in labels]
    out = []
    for i, (lb, c) in enumerate(zip(labels, cut, strict=True)):
        if len(lb) <= LABEL_CHARS and cut.count(c) == 1:
            out.append(lb)
        else:
            tag = f"~{i + 1}"
            out.append(lb[:LABEL_CHARS - len(tag)] + tag)
    if len(set(out)) != len(out):  # a kept label that looks like an abbreviation
        out = [f"{lb[:LABEL_CHARS - len(f'~{i + 1}')]}~{i + 1}" for i, lb in enumerate(labels)]
    return out


def bdf_bytes(x_volts: NDArray[np.float64], fs: float, labels: list[str]) -> bytes:
    """A BDF file of the samples (microvolts, 24 bit); non-finite samples as 0."""
    import edfio

    uv = np.where(np.isfinite(x_volts), x_volts, 0.0) * 1e6
    record_s = record_duration(fs)
    per_record = round(fs * record_s)
    pad = -uv.shape[0] % per_record
    uv = np.vstack([uv, np.zeros((pad, uv.shape[1]))])
    signals = [edfio.BdfSignal(uv[:, i], fs, label=lb, physical_dimension="uV",
                               physical_range=_physical_range(uv[:, i]),
                               digital_range=BDF_DIGITAL)
               for i, lb in enumerate(bdf_labels(labels))]
    buf = io.BytesIO()
    edfio.Bdf(signals, data_record_duration=record_s).write(buf)
    return buf.getvalue()


def trial_window(rec: EmgRecording, trial_id: int) -> tuple[float, float] | None:
    """The trial's span on the recording's own clock, clipped to the recording."""
    for t in rec.trials:
        if t["trial_id"] == trial_id and t.get("stop") is not None:
            start = max(float(t["start"]), rec.t_start or -math.inf) - rec.time_offset_s
            stop = min(float(t["stop"]), rec.t_end or math.inf) - rec.time_offset_s
            if stop > start:
                return start, stop + 0.5 / rec.fs
    return None


def _coverage(rec: EmgRecording, trial_id: int) -> str:
    """What the file does not hold, said in its description: a recording a killed
    server left (finalised with the samples it held), a trial it covers only in part."""
    said = ""
    if rec.status == "interrupted":
        said += (". The recording was interrupted (its server stopped) and kept the "
                 "samples written until then")
    span = next((t for t in rec.trials if t["trial_id"] == trial_id), None)
    if span is not None and not span.get("complete", True) and span.get("stop") is not None:
        held = (min(float(span["stop"]), rec.t_end or math.inf)
                - max(float(span["start"]), rec.t_start or -math.inf))
        said += (f". This file holds {max(held, 0.0):.2f} s of the trial's "
                 f"{float(span['stop']) - float(span['start']):.2f} s")
    return said


def sidecar(rec: EmgRecording, montage: EmgMontage, task: str, description: str,
            mains_hz: int, processing: dict[str, Any], n: int,
            info: dict[str, Any] | None = None) -> dict[str, Any]:
    """`_emg.json` of one trial; what the lab did not state (amplifier model, hardware
    filters, institution) is "n/a", said rather than left out."""
    info = info or {}
    electrodes = sorted({c.get("electrode_type") or "" for c in montage.channels} - {""})
    refs = sorted({c.get("reference") or "bipolar" for c in montage.channels})
    chain = ", ".join(f"{k}={v}" for k, v in processing.items())
    return {
        "TaskName": task,
        "TaskDescription": f"{description}. Stored raw (no filter applied to the file; "
                           f"zeros pad the last {record_duration(rec.fs):g} s data record "
                           f"after "
                           f"RecordingDuration); "
                           f"the study's analysis chain: {chain}",
        "EMGPlacementScheme": "Other",
        "EMGPlacementSchemeDescription": montage.placement_scheme or "see channels.tsv",
        "EMGReference": "; ".join(refs),
        "EMGChannelCount": len(montage.channels),
        "SamplingFrequency": rec.fs,
        "PowerLineFrequency": mains_hz,
        "SoftwareFilters": "n/a",
        "RecordingDuration": n / rec.fs,
        "RecordingType": "continuous",
        "Manufacturer": "n/a",
        "ManufacturersModelName": "n/a",
        "DeviceSerialNumber": "n/a",
        "ElectrodeManufacturer": "n/a",
        "ElectrodeManufacturersModelName": "; ".join(electrodes) or "n/a",
        "HardwareFilters": "n/a",
        "SoftwareVersions": f"ExoStudy EMG store, source {rec.source}",
        "InstitutionName": info.get("institution_name") or "n/a",
        "InstitutionAddress": info.get("institution_address") or "n/a",
        "InstitutionalDepartmentName": info.get("institution_department") or "n/a",
        "Instructions": info.get("instructions") or "n/a",
    }


def channels_rows(montage: EmgMontage, bad: dict[int, int]) -> tuple[list[str], list[list[Any]]]:
    """`_channels.tsv` of the montage (status bad where samples were not finite)."""
    cols = ["name", "type", "units", "target_muscle", "placement_scheme",
            "placement_description", "reference", "status", "status_description",
            "description"]
    names = bdf_labels([c["label"] for c in montage.channels])
    rows = []
    for i, c in enumerate(montage.channels):
        ied = c.get("inter_electrode_distance_mm")
        where = c.get("placement") or "n/a"
        if ied:
            where = f"{where}; inter-electrode distance {ied:g} mm"
        if c.get("electrode_type"):
            where = f"{where}; {c['electrode_type']}"
        rows.append([names[i], "EMG", "uV", f"{c['side']} {c['muscle']}", "other",
                     where, c.get("reference") or "bipolar",
                     "bad" if bad.get(i) else "good",
                     f"{bad[i]} non-finite samples written as 0" if bad.get(i) else "n/a",
                     f"montage label {c['label']}"])
    return cols, rows


def trial_files(settings_dir: Path, rec: EmgRecording, montage: EmgMontage, trial_id: int,
                stem: str, task: str, description: str, mains_hz: int,
                processing: dict[str, Any], info: dict[str, Any] | None = None
                ) -> Iterator[tuple[str, Any]]:
    """(path suffix, content) of one trial's EMG: `_emg.bdf`, `_emg.json` and the
    channels' rows; nothing if the recording has no samples in the trial."""
    window = trial_window(rec, trial_id)
    if window is None:
        return
    path = settings_dir / f"{rec.id}.emgc"
    t, x = store.read_window(path, *window)
    if t.size < 2:
        return
    bad = {i: int((~np.isfinite(x[:, i])).sum()) for i in range(x.shape[1])}
    labels = [c["label"] for c in montage.channels]
    yield f"{stem}_emg.bdf", bdf_bytes(x, rec.fs, labels)
    yield f"{stem}_emg.json", sidecar(rec, montage, task,
                                      description + _coverage(rec, trial_id), mains_hz,
                                      processing, t.size, info)
    yield f"{stem}_channels.tsv", channels_rows(montage, bad)
    yield "shift", float(t[0] + rec.time_offset_s)
