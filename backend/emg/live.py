"""Live EMG from LSL: a session subscribes to a stream of type `EMG` (as to a marker
stream), and a thread records it to the store in chunks.

The thread pulls chunks from its inlet, adds the inlet's `time_correction()` (liblsl's
running estimate of the sender's clock against ours) so every timestamp is on this
server's LSL clock, the session clock of markers and trials, picks the montage's
channels in montage order, converts to volts and appends to the recording file. It
never touches the control worker (a separate process) and holds at most one pull and
one file chunk in memory.

Bad streams: a stream whose type is not EMG, whose channel units are not voltages,
whose labels do not match the montage, or whose nominal rate is not positive is refused
when subscribing (422) and, if it changes later, when connecting (the subscription is
closed with the reason). A stream that is lost ends its recording (flag `stream_lost`);
when it comes back a new recording starts (flag `stream_restarted`). NaN samples,
clipping, flat channels, gaps and a rate that disagrees with the timestamps are flagged
in the recording's quality, never dropped.

The live page's strip: each pulled block also goes through `LiveEnvelope` (causal
envelope, decimated, with per-channel flags), whose messages reach the consoles over the
live WebSocket. A pull waits for the first sample (up to `_PULL_TIMEOUT_S`) and then
takes what has arrived without waiting: liblsl's `pull_chunk` with a timeout waits
until its buffer is full or the timeout ends, which would hold every block for 0.2 s.
Both pulls land in one preallocated array of the stream's own type (liblsl copies into
it), not in Python lists of numbers: at 16 channels and 2 kHz the lists cost more CPU
than everything done with the samples afterwards.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.emg import EmgAnalysisSettings, EmgMontage, EmgStream
from backend.db.sessions import study_of_session
from backend.emg import recordings
from backend.emg.live_envelope import LiveEnvelope, Publish
from backend.emg.quality_summary import STREAM_LOST, STREAM_RESTARTED
from backend.lsl.backoff import backoff_delays
from backend.lsl.names import Property, lsl_errors, predicate
from controller.emg.processing import EmgProcessing, EmgSettingsError

log = logging.getLogger(__name__)

_PULL_TIMEOUT_S = 0.2
#: Most samples one pull takes (0.5 s at 4 kHz).
_MAX_PULL = 2048
_RESOLVE_TIMEOUT_S = 1.0
#: Wait for a resolved stream's full description.
_INFO_TIMEOUT_S = 5.0
#: numpy types of liblsl's numeric channel formats (pylsl.cf_float32 = 1 ... cf_int64 = 7;
#: 3 is text, refused by `layout_of`), the type a pull's buffer must have.
_SAMPLE_TYPES: dict[int, type[np.generic]] = {
    1: np.float32, 2: np.float64, 4: np.int32, 5: np.int16, 6: np.int8, 7: np.int64}
ALIGNMENT = "LSL: timestamps plus the inlet's time_correction(), on this server's LSL clock"


@dataclass(frozen=True, slots=True)
class StreamLayout:
    """What a stream's description says, checked against the montage."""

    columns: tuple[int, ...]
    volts: tuple[float, ...]
    fs: float


def describe(info: Any) -> tuple[list[str], list[str]]:
    """Channel labels and units from an LSL stream info's description (labels default
    to the channel number, units to "")."""
    labels: list[str] = []
    units: list[str] = []
    ch = info.desc().child("channels").child("channel")
    while not ch.empty() and len(labels) < info.channel_count():
        labels.append(ch.child_value("label") or str(len(labels) + 1))
        units.append(ch.child_value("unit") or "")
        ch = ch.next_sibling()
    while len(labels) < info.channel_count():
        labels.append(str(len(labels) + 1))
        units.append("")
    return labels, units


def check_layout(stream_type: str, fs: float, labels: list[str], units: list[str],
                 montage: EmgMontage, ignore: list[str]) -> StreamLayout:
    """Whether a stream can be recorded with this montage; ValueError saying why not."""
    if stream_type.strip().casefold() != "emg":
        raise ValueError(f"stream type is {stream_type!r}, not 'EMG'")
    if not fs > 0:
        raise ValueError(f"stream has no regular sampling rate (nominal {fs} Hz); EMG "
                         "needs one")
    cols = recordings.map_channels(montage, labels, ignore)
    volts = []
    for i in cols:
        try:
            volts.append(recordings.volts_per_unit(units[i]))
        except ValueError as exc:
            raise ValueError(f"channel {labels[i]!r}: {exc}") from exc
    return StreamLayout(tuple(cols), tuple(volts), float(fs))


#: liblsl's channel-format code for text (pylsl.cf_string), checked without loading pylsl.
_CF_STRING = 3


def layout_of(info: Any, montage: EmgMontage, ignore: list[str]) -> StreamLayout:
    """`check_layout` on a resolved stream; a stream of text is refused as XDF import
    refuses one (its samples are not numbers to filter)."""
    if int(info.channel_format()) == _CF_STRING:
        raise ValueError("its channels hold text (channel_format string), not EMG samples; "
                         "an EMG stream carries numbers (float32, double64 or integers)")
    labels, units = describe(info)
    return check_layout(info.type(), float(info.nominal_srate()), labels, units, montage,
                        ignore)


def resolve(name: str, source_id: str, timeout: float = _RESOLVE_TIMEOUT_S) -> Any:
    """The stream's info as resolved (to open inlets with), or None when not visible."""
    import pylsl

    prop: Property = "source_id" if source_id else "name"
    found = pylsl.resolve_bypred(predicate(prop, source_id or name), minimum=1,
                                 timeout=timeout)
    return found[0] if found else None


def full_info(info: Any) -> Any:
    """The stream's full info with its description, or None when it is gone.

    A resolved info holds only the stream's header: the description (channel labels and
    units) comes from the outlet itself, through an inlet's `info()`. (The full info
    cannot open an inlet in turn: it lacks the resolved info's addresses.)"""
    import pylsl

    lost, timed_out = lsl_errors(pylsl)
    inlet = pylsl.StreamInlet(info, max_buflen=1, recover=False)
    try:
        return inlet.info(timeout=_INFO_TIMEOUT_S)
    except (lost, timed_out, TimeoutError):
        return None  # gone again between resolving and asking
    finally:
        del inlet


def resolve_described(name: str, source_id: str) -> Any:
    """`resolve` then `full_info`: the description of a visible stream, or None."""
    info = resolve(name, source_id)
    return None if info is None else full_info(info)


def study_processing(db: Session, session_id: int) -> EmgProcessing:
    """The processing chain of the session's study (defaults when unset or unusable)."""
    sid = study_of_session(db, session_id)
    row = db.get(EmgAnalysisSettings, sid) if sid is not None else None
    try:
        return EmgProcessing.from_dict(row.processing) if row is not None else EmgProcessing()
    except (EmgSettingsError, TypeError):
        return EmgProcessing()


def pull_buffer(info: Any) -> NDArray[Any]:
    """The array `pull` fills: `_MAX_PULL` rows of the stream's channels in its type."""
    fmt = int(info.channel_format())
    if fmt not in _SAMPLE_TYPES:
        raise ValueError(f"its channel format (liblsl code {fmt}) is not a number type; an "
                         "EMG stream carries numbers (float32, double64 or integers)")
    return np.zeros((_MAX_PULL, int(info.channel_count())), dtype=_SAMPLE_TYPES[fmt])


def pull(inlet: Any, buf: NDArray[Any]) -> list[float]:
    """Wait up to `_PULL_TIMEOUT_S` for a sample, then take what else has arrived, into
    the first rows of `buf` (`pull_buffer`); returns their timestamps."""
    _, first = inlet.pull_chunk(timeout=_PULL_TIMEOUT_S, max_samples=1, dest_obj=buf)
    if not first:
        return []
    _, rest = inlet.pull_chunk(timeout=0.0, max_samples=buf.shape[0] - 1, dest_obj=buf[1:])
    return [*first, *rest]


class EmgInlet:
    """Records one EMG subscription until stopped."""

    def __init__(self, engine: Engine, settings: Settings, subscription_id: int,
                 publish: Publish | None = None) -> None:
        self.engine = engine
        self.settings = settings
        self.subscription_id = subscription_id
        #: Where the live envelope's messages go (the consoles' WebSocket); None: nowhere.
        self.publish = publish
        #: The strip's envelope of the current connection (None while not connected).
        self.envelope: LiveEnvelope | None = None
        self.connected = False
        self.samples = 0
        #: The newest sample recorded, on the session clock (None before the first).
        self.last_time: float | None = None
        self.recordings: list[int] = []
        self.failure = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"emg-inlet-{subscription_id}")

    def start(self) -> None:
        """Begin resolving and recording."""
        self._thread.start()

    def stop(self, wait: bool = True) -> None:
        """Stop (the current recording is finished and kept)."""
        self._stop.set()
        if wait and self._thread is not threading.current_thread():
            self._thread.join(5.0)

    @property
    def alive(self) -> bool:
        """The recording thread still runs."""
        return self._thread.is_alive()

    def _sub(self, db: Session) -> tuple[EmgStream, EmgMontage]:
        sub = db.get(EmgStream, self.subscription_id)
        if sub is None:
            raise LookupError(f"EMG subscription {self.subscription_id} is gone")
        montage = db.get(EmgMontage, sub.montage_id)
        assert montage is not None
        return sub, montage

    def _fail(self, why: str) -> None:
        self.failure = why
        log.warning("EMG subscription %d closed: %s", self.subscription_id, why)
        with Session(self.engine) as db:
            sub = db.get(EmgStream, self.subscription_id)
            if sub is not None:
                sub.active = False
                sub.error = why[:1000]
                db.commit()

    def _run(self) -> None:
        delays = backoff_delays()
        restarted = False
        while not self._stop.is_set():
            try:
                with Session(self.engine) as db:
                    sub, _ = self._sub(db)
                    name, source_id = sub.name, sub.source_id
                info = resolve(name, source_id)
                if info is None:
                    continue
                self._record(info, restarted)
                restarted = True
                delays = backoff_delays()
            except ValueError as exc:  # the stream no longer fits: stop, say why
                self._fail(str(exc))
                return
            except LookupError:
                return
            except Exception as exc:  # liblsl raises RuntimeError and others
                log.warning("EMG stream %d: %s", self.subscription_id, exc)
            if self._stop.wait(next(delays)):
                return

    def _record(self, info: Any, restarted: bool) -> None:
        import pylsl

        with Session(self.engine) as db:
            sub, montage = self._sub(db)
            # LSL's default buffer (6 min of samples): a server busy for a while catches
            # up afterwards instead of losing samples.
            inlet = pylsl.StreamInlet(info, max_buflen=360, recover=False)
            layout = layout_of(inlet.info(timeout=_INFO_TIMEOUT_S), montage,
                               list(sub.ignored_labels))
            buf = pull_buffer(info)
            inlet.open_stream(timeout=5.0)
            rec = recordings.RecordingWriter(
                db, self.settings, sub.session_id, montage, "lsl", layout.fs, 0.0, ALIGNMENT,
                f"{info.name()}.lsl", stream_id=sub.id)
            self.recordings.append(rec.row.id)
            if restarted:
                rec.quality.flag(STREAM_RESTARTED)
            cols = np.asarray(layout.columns)
            volts = np.asarray(layout.volts)
            envelope = LiveEnvelope(layout.fs, [c["label"] for c in montage.channels],
                                    sub.session_id, sub.id,
                                    study_processing(db, sub.session_id), self.publish)
            envelope.recording_id = rec.row.id
            self.envelope = envelope
            self.connected = True
            try:
                correction = inlet.time_correction(timeout=5.0)
                while not self._stop.is_set():
                    ts = pull(inlet, buf)
                    if not ts:
                        continue
                    correction = inlet.time_correction(timeout=1.0)
                    # A new float64 array: the writer and the strip keep references.
                    x = buf[:len(ts), cols] * volts
                    t = np.asarray(ts, dtype=np.float64) + correction
                    rec.append(t, x)
                    self.samples += len(ts)
                    self.last_time = float(t[-1])
                    try:
                        envelope.clock_correction_s = float(correction)
                        envelope.push(t, x)
                    except Exception as exc:  # the strip must never stop the recording
                        log.warning("EMG strip of stream %d: %s", self.subscription_id, exc)
            except (*lsl_errors(pylsl), TimeoutError):
                log.warning("EMG stream %s was lost; resolving it again", info.name())
                rec.quality.flag(STREAM_LOST)
            finally:
                self.connected = False
                self.envelope = None
                try:
                    inlet.close_stream()
                except Exception:
                    pass
                if rec.writer.appended:
                    rec.finish()
                else:
                    rec.abort()  # connected, got nothing: no empty recording
                    self.recordings.remove(rec.row.id)


class EmgLab:
    """The EMG inlets of one server."""

    def __init__(self, enabled: bool, engine: Engine, settings: Settings,
                 publish: Publish | None = None) -> None:
        self.enabled = enabled
        self.engine = engine
        self.settings = settings
        #: Where every inlet sends its live envelope (`LiveStream.broadcast_json`).
        self.publish = publish
        self.inlets: dict[int, EmgInlet] = {}

    def start(self) -> None:
        """Resume the active subscriptions."""
        if not self.enabled:
            return
        with Session(self.engine) as db:
            ids = list(db.scalars(select(EmgStream.id).where(EmgStream.active)))
        for sub_id in ids:
            self.subscribe(sub_id)

    def stop(self) -> None:
        """Stop every inlet (recordings are finished and kept)."""
        inlets = list(self.inlets.values())
        for inlet in inlets:
            inlet.stop(wait=False)
        for inlet in inlets:
            inlet.stop()
        self.inlets.clear()

    def subscribe(self, sub_id: int) -> None:
        """Start recording subscription `sub_id`."""
        if not self.enabled or sub_id in self.inlets:
            return
        inlet = EmgInlet(self.engine, self.settings, sub_id, self.publish)
        self.inlets[sub_id] = inlet
        inlet.start()

    def unsubscribe(self, sub_id: int) -> None:
        """Stop recording (what is recorded stays)."""
        inlet = self.inlets.pop(sub_id, None)
        if inlet is not None:
            inlet.stop()
