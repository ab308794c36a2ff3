"""``open_window``: on a ``hot`` label with the window closed the agent stands up, walks to
the window (root assistance measured) and slides the pane open with its palm's proximity
grasp (simenv.agents.window_open)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simenv.agents.scripted import PLANNERS
from simenv.agents.window_open import open_spot, plan_open_window, plan_window_pull
from simenv.core.errors import SimenvError
from simenv.room.room import Room
from simenv.room.session import PERCEPTION_FPS, GestureEvent


def _rehearse_hot(session, room_grasps: bool = True, until_after: str | None = None):
    """Run InteractionRoom-v0 on ``session`` labelled hot over its whole length in the
    discomfort_closed scenario, deciding open_window at 0.2 s; with ``room_grasps``
    False every proximity grasp is refused (the hand can then only push); with
    ``until_after`` a stage name, only until the chain's next stage starts. Returns the
    env, its log entry, and per step (t, window opening m, grasp active)."""
    from simenv.envs.interaction_room import InteractionRoomEnv

    env = InteractionRoomEnv(session, gestures=[GestureEvent("hot", 0.0, session.duration)],
                             scenario="discomfort_closed")
    if not room_grasps:
        env.room.set_grasp = lambda data, hand, name, on: False
    env.reset(seed=0)
    env.spot = open_spot(env.room, env.data)[0]  # where the walk should end (window closed)
    eq = env.model.equality("grasp/right_hand/window").id
    act, decide = env.reactions.index("open_window"), int(round(0.2 * PERCEPTION_FPS))
    k, truncated, rows = 0, False, []
    while not truncated:
        *_, truncated, _ = env.step(act if k == decide else 0)
        k += 1
        rows.append((k / PERCEPTION_FPS, env.room.object_states(env.data)["window"],
                     bool(env.data.eq_active[eq])))
        names = [s["stage"] for s in (env.log[0].get("stages") or [])] if env.log else []
        if until_after in names[:-1]:
            break
    (entry,) = env.log
    return env, entry, rows


@pytest.fixture(scope="module")
def real_clip(shared_data):
    from simenv.io import msr_action3d

    return msr_action3d.read(shared_data / "gestures" / "msr_action3d" /
                             "a01_s01_e01_skeleton3D.txt")


def test_real_session_labelled_hot_opens_the_window_through_the_grasp(real_clip):
    """A real MSR Action3D recording labelled hot: stand up (unassisted), turn on the feet
    and walk to the window on its own legs (no help, measured), the palm's grasp closes on
    the handle and the hand drags the pane past the open threshold while it holds it."""
    env, entry, rows = _rehearse_hot(real_clip)
    assert entry["started"] and entry["gesture"] == "hot"
    # (The return to the chair follows in the chain; the environment ends a chain once its
    # object succeeded.)
    assert [s["stage"] for s in entry["stages"]][:3] == ["stand_up", "walk", "pull"]
    stages = {s["stage"]: s for s in entry["stages"]}
    assert "assistance" not in stages["stand_up"]
    assert np.linalg.norm(np.asarray(stages["walk"]["pelvis_end"][:2]) - env.spot) < 0.15
    for name in ("walk", "pull"):
        a = stages[name]["assistance"]
        assert a["steps"] > 0 and a["max_n"] == 0.0 and a["max_torque_nm"] == 0.0
        assert not stages[name]["outcome"]["fell"]
    assert entry["assistance"]["max_n"] == 0.0 and not entry.get("fell")
    assert entry["grasped"] is True
    assert entry["success"] is True
    threshold = env.room.objects["window"].threshold
    held = [t for t, _, on in rows if on]
    crossed = next(t for t, w, _ in rows if w > threshold)
    assert held and held[0] < crossed <= held[-1] + 1e-9  # opened while the hand held it
    assert max(w for t, w, _ in rows if t < held[0]) < 0.02  # nothing moved it before
    assert entry["t_object_changed"] == pytest.approx(crossed)
    assert env.room.object_labels(env.data)["window"] == "open"
    assert env.room.assist_wrench(env.data) == (0.0, 0.0)


def test_without_the_grasp_the_hand_does_not_open_it(real_clip):
    """The same reaction with every grasp refused: the hand moving away from the handle's
    face cannot drag the pane, which stays closed (so it is the grasp that opens it).
    Stepped until the pull has ended: the return stages after it walk away from the
    window (the success case above runs them)."""
    env, entry, rows = _rehearse_hot(real_clip, room_grasps=False, until_after="pull")
    assert entry["started"] and entry["grasped"] is False
    names = [s["stage"] for s in entry["stages"]]
    assert names[:3] == ["stand_up", "walk", "pull"] and len(names) == 4  # the pull ended
    # Not a success: the object never changed, at no step of the walk or the pull.
    assert entry["t_object_changed"] is None
    assert max(w for _, w, _ in rows) < env.room.objects["window"].threshold


def test_open_window_needs_a_closed_window():
    room = Room("discomfort")  # the window starts open 0.45 m
    data = room.make_data()
    mujoco.mj_forward(room.model, data)
    assert PLANNERS["open_window"] is plan_open_window
    with pytest.raises(SimenvError, match="already open"):
        plan_open_window(room, data)
    with pytest.raises(SimenvError, match="already open"):
        plan_window_pull(room, data)
