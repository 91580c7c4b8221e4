"""Baseline conditions in an evaluation session's plan: counterbalanced and blinded with
the controllers, for the lift tasks only by default, and refused clearly when asked
for without a task to run them in."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from backend.study.trials import is_lift_task

TASKS = ["squat-sequence", "stoop-sequence", "walking", "stairs"]


def _sessions(client: TestClient, n: int) -> list[int]:
    study = client.post("/api/studies", json={"name": "baselines"})
    assert study.status_code == 201, study.text
    sid = study.json()["id"]
    out = []
    for i in range(n):
        p = client.post(f"/api/studies/{sid}/participants", json={"code": f"P{i + 1:02d}"})
        assert p.status_code == 201, p.text
        s = client.post(f"/api/participants/{p.json()['id']}/sessions",
                        json={"kind": "evaluation", "precompression_pct": 25})
        assert s.status_code == 201, s.text
        out.append(s.json()["id"])
    return out


def _plan(client: TestClient, session_id: int, **body: Any) -> list[dict[str, Any]]:
    r = client.post(f"/api/sessions/{session_id}/trials/plan", json=body)
    assert r.status_code == 201, r.text
    return list(r.json())


def _order(plan: list[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(t["controller"] for t in plan))


def test_baselines_rotate_with_the_controllers_for_lift_tasks_only(
        client: TestClient) -> None:
    sessions = _sessions(client, 4)
    plans = [_plan(client, s, tasks=TASKS, include_eumc=False, include_baselines=True)
             for s in sessions]
    # UMC, PEC, springs free, no exoskeleton rotate: each leads once in four participants.
    orders = [_order(p) for p in plans]
    assert orders[0] == ["umc", "pec", "springs_free", "no_exoskeleton"]
    assert orders[1] == ["pec", "springs_free", "no_exoskeleton", "umc"]
    assert [o[0] for o in orders] == ["umc", "pec", "springs_free", "no_exoskeleton"]
    for plan in plans:
        for t in plan:
            expected = ["squat-sequence", "stoop-sequence"] if t["controller"] in (
                "springs_free", "no_exoskeleton") else TASKS
            assert t["task"] in expected
        by_ctl = {c: [t["task"] for t in plan if t["controller"] == c] for c in _order(plan)}
        assert by_ctl["springs_free"] == ["squat-sequence", "stoop-sequence"]
        assert by_ctl["umc"] == TASKS
        assert [t["planned_order"] for t in plan] == list(range(len(plan)))


def test_blinded_labels_cover_the_baselines(client: TestClient) -> None:
    sessions = _sessions(client, 2)
    for s in sessions:
        _plan(client, s, tasks=["squat-sequence"], include_baselines=True)
    keys = []
    for pid in (1, 2):
        r = client.get(f"/api/participants/{pid}/conditions")
        assert r.status_code == 200, r.text
        keys.append({row["label"]: row["controller"] for row in r.json()})
    # Letters in the order met: the first participant meets UMC first, the second PEC,
    # so a letter says nothing about which condition (baseline or not) it stands for.
    assert keys[0] == {"A": "umc", "B": "pec", "C": "springs_free", "D": "no_exoskeleton",
                       "E": "eumc"}
    assert keys[1] == {"A": "pec", "B": "springs_free", "C": "no_exoskeleton", "D": "umc",
                       "E": "eumc"}


def test_baseline_tasks_named_explicitly(client: TestClient) -> None:
    (s,) = _sessions(client, 1)
    plan = _plan(client, s, tasks=["paper-evaluation"], include_eumc=False,
                 include_baselines=True, baseline_tasks=["lift-evaluation"])
    assert [(t["controller"], t["task"]) for t in plan] == [
        ("umc", "paper-evaluation"), ("pec", "paper-evaluation"),
        ("springs_free", "lift-evaluation"), ("no_exoskeleton", "lift-evaluation")]


def test_no_baselines_unless_asked(client: TestClient) -> None:
    (s,) = _sessions(client, 1)
    plan = _plan(client, s, tasks=["squat-sequence"])
    assert _order(plan) == ["umc", "pec", "eumc"]


def test_bad_baseline_requests_are_4xx_and_store_nothing(client: TestClient) -> None:
    (s,) = _sessions(client, 1)
    r = client.post(f"/api/sessions/{s}/trials/plan",
                    json={"tasks": ["walking", "stairs"], "include_baselines": True})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "baseline_tasks"]
    assert "none of the tasks" in detail["msg"] and "walking" in detail["msg"]
    r = client.post(f"/api/sessions/{s}/trials/plan",
                    json={"tasks": ["squat-sequence"], "baseline_tasks": ["squat-sequence"]})
    assert r.status_code == 422, r.text
    assert "include_baselines" in r.text
    r = client.post(f"/api/sessions/{s}/trials/plan",
                    json={"tasks": ["squat-sequence"], "include_baselines": True,
                          "baseline_tasks": []})
    assert r.status_code == 422, r.text
    assert client.get(f"/api/sessions/{s}/trials").json() == []


def test_lift_tasks_by_name() -> None:
    assert is_lift_task("squat-sequence") and is_lift_task("Stoop_left")
    assert is_lift_task("box LIFT 10 kg")
    assert not is_lift_task("walking") and not is_lift_task("paper-evaluation")
