"""A virtual study's data-collection phase: the other virtual participants record the
demonstrations and the server segments them from the simulation's truth; the segments
are what the study's model set is fitted from."""

from __future__ import annotations

from backend.analysis.virtual_study_config import VirtualStudyConfig
from backend.analysis.virtual_study_driver import (
    Driver,
    ok,
    participant_body,
    script_duration_s,
)
from controller.device.base import SAMPLE_PERIOD_S


def collect(d: Driver, cfg: VirtualStudyConfig, study_id: int) -> list[int]:
    """Record every data-collection participant, then segment the recordings; the
    segment ids.

    The recordings are segmented once all are made and the simulated wearer is back at
    real time (that of the evaluation's first participant, as the fitting of the sets
    after this wants): segmenting between recordings left the sped-up simulation
    running, its ticks stored and never read (a tenth of a small study's ticks). Same
    recordings, segmented in the same order."""
    recordings: list[int] = []
    for i in range(cfg.data_participants):
        seed = cfg.data_seed(i)
        p = ok(d.c.post(f"/api/studies/{study_id}/participants",
                        json=participant_body(seed, f"D{i + 1:02d}")), 201)
        sess = ok(d.c.post(f"/api/participants/{p['id']}/sessions",
                           json={"kind": "data_collection", "precompression_pct": 25}), 201)
        for script in cfg.data_scripts:
            # The first repetition and 1.5 s into the next one's first stand (no lift is
            # cut at the end). The wearer starts with the recording, and the worker ends
            # it after that much device time: the same samples at any speed, however
            # late the stop below comes.
            end_s = script_duration_s(seed, script) + 1.5
            d.speed = cfg.collection_speed
            rec = ok(d.c.post(f"/api/sessions/{sess['id']}/recordings", json={
                "label": script, "duration_s": end_s,
                "simulation": {"seed": seed, "script": script,
                               "speed": cfg.collection_speed}}), 201)
            # The worker's tick count is the device's sample number since the swap.
            d.wait_ticks(round(end_s / SAMPLE_PERIOD_S))
            ok(d.c.post(f"/api/recordings/{rec['id']}/stop"))
            recordings.append(rec["id"])
        d.log(f"data collection: D{i + 1:02d} recorded")
    d.simulate(cfg.eval_seed(0), cfg.eval_script, 1.0)
    segment_ids: list[int] = []
    for rec_id in recordings:
        segs = ok(d.c.post(f"/api/recordings/{rec_id}/segment"))
        segment_ids += [s["id"] for s in segs
                        if s["label"] in ("squat", "stoop_left", "stoop_right")]
    d.log(f"data collection: {len(recordings)} recordings, {len(segment_ids)} segments")
    return segment_ids
