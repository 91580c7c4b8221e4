"""EMG files after a crash or an erasure: finalise what a killed writer left, find orphans.

A live recording's row says "recording" and its samples go to `<id>.emgc.part`, chunk
by chunk (`backend.emg.store`). When the server is killed mid-recording, `recover` (run
at start-up, before any new recording can take an id) keeps every whole chunk the
`.part` holds: the file is cut after its last whole chunk, renamed into place, and the
row gets its samples, span, hash, trials and quality, status "interrupted" and the flag
`interrupted` (what was cut is said in `quality["recovery"]`). Rows past the last chunk
were in the server's memory (at most `store.CHUNK_ROWS`) and died with it.

Files whose row is gone (an erasure whose file deletion failed, a crash between the
two) are orphans: `orphans` lists them for `exostudy doctor`, and a new recording that
gets a reused id moves such a file aside (`set_aside`) instead of overwriting it.
"""

from __future__ import annotations

import logging
import os
import re
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.emg import EmgRecording
from backend.emg import store
from backend.emg.quality_summary import INTERRUPTED, QualitySummary

log = logging.getLogger(__name__)

#: Recording files: `<id>.emgc`, its `.part`, and files moved aside.
_FILE = re.compile(r"^(\d+)\.emgc(\.part|\.orphan-[0-9TZ]+)?$")


def _finalise(db: Session, row: EmgRecording, folder: Path) -> str:
    """Keep what the files of one interrupted recording hold; what was done, in words."""
    from backend.emg.recordings import covered_trials

    final = folder / f"{row.id}.emgc"
    part = final.with_name(final.name + ".part")
    note = "the file was complete"
    if not final.exists():
        if not part.exists():
            note = "no file was left: no samples were written"
        else:
            size = part.stat().st_size
            try:
                good, _rows = store.whole_length(part)
            except store.EmgStoreError:
                good = 0
            if good == 0:
                note = (f"the {size}-byte .part holds no whole header: kept as "
                        f"{set_aside(part).name}")
            else:
                with open(part, "r+b") as f:
                    f.truncate(good)
                    f.flush()
                    os.fsync(f.fileno())
                os.replace(part, final)
                note = (f"kept the .part's {good} bytes of whole chunks"
                        + (f", cut {size - good} bytes of a chunk being written"
                           if size > good else ""))
    quality = QualitySummary(row.fs, list(row.labels))
    rows, first, last = 0, None, None
    if final.exists():
        damage: list[str] = []
        for t, x in store.iter_chunks(final, damage):
            quality.add(t, x)
            rows += t.size
            if t.size:
                first = float(t[0]) if first is None else first
                last = float(t[-1])
        if damage:  # kept as it is (nothing is deleted); what reads back is counted
            note += f"; the file is damaged after {rows} samples: {damage[0]}"
        row.sha256 = store.file_sha256(final)
        row.size_bytes = final.stat().st_size
    quality.finish()
    quality.flag(INTERRUPTED)
    off = row.time_offset_s
    row.n_samples = rows
    row.t_start = None if first is None else first + off
    row.t_end = None if last is None else last + off
    row.trials = covered_trials(db, row.session_id, row.t_start, row.t_end)
    row.quality = {**quality.to_dict(), "recovery": note}
    row.status = "interrupted"
    return f"EMG recording {row.id}: {rows} samples kept ({note})"


def recover(db: Session, folder: Path) -> list[str]:
    """Finalise every recording a killed server left "recording" (committed); what was
    done for each. Only for a server start: a running server's recordings are live."""
    done = []
    for row in db.scalars(select(EmgRecording).where(EmgRecording.status == "recording")):
        try:
            done.append(_finalise(db, row, folder))
        except Exception as exc:  # one recording's files must not keep the server down
            log.exception("recovering EMG recording %s failed", row.id)
            row.status = "interrupted"
            row.quality = {**(row.quality or {}), "recovery": f"recovery failed: {exc}"}
            done.append(f"EMG recording {row.id}: recovery failed ({exc}); its files are "
                        "kept as they are")
    db.commit()
    return done


def set_aside(path: Path) -> Path:
    """Rename a file that is in the way to `<name>.orphan-<UTC time>`: never overwritten,
    never silently deleted; `exostudy doctor` lists it."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S%fZ")
    aside = path.with_name(f"{path.name}.orphan-{stamp}")
    os.replace(path, aside)
    log.warning("EMG file %s had no recording row: moved to %s", path, aside.name)
    return aside


def orphans(db: Session, folder: Path) -> list[Path]:
    """Recording files no row claims (and files set aside), sorted."""
    if not folder.is_dir():
        return []
    ids = set(db.scalars(select(EmgRecording.id)))
    out = []
    for p in folder.iterdir():
        m = _FILE.match(p.name)
        if m and (int(m.group(1)) not in ids or (m.group(2) or "").startswith(".orphan")):
            out.append(p)
    return sorted(out)


def delete_files(folder: Path, recording_ids: list[int]) -> list[str]:
    """Remove the files (and `.part`s) of deleted recordings, after their rows' commit:
    a failure leaves an orphan (logged; `exostudy doctor` lists it), never a row
    without its file. The failures, in words."""
    failed = []
    for rid in recording_ids:
        for p in (folder / f"{rid}.emgc", folder / f"{rid}.emgc.part"):
            try:
                p.unlink(missing_ok=True)
            except OSError as exc:
                failed.append(f"{p}: {exc}")
                log.error("could not delete the EMG file of erased recording %s: %s "
                          "(`exostudy doctor` lists it)", rid, exc)
    return failed
