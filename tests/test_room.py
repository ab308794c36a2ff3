"""The room scene: compilation, object states, scenario validation, a stable seated agent,
and object states that change through simulated physics."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from simenv.core.errors import ScenarioError, SimenvError
from simenv.room.room import GRASP_RADIUS, Room
from simenv.room.scenario import REACTIONS, list_scenarios, load_scenario

OBJECTS = ("window", "curtain", "hifi", "cigarette", "door")


def _warnings(data: mujoco.MjData) -> int:
    return int(sum(data.warning[w].number for w in range(len(data.warning))))


def test_bundled_scenarios_compile():
    assert {"default", "discomfort"} <= set(list_scenarios())
    for name in ("default", "discomfort"):
        r = Room(name)
        data = r.make_data()
        assert set(r.objects) == set(OBJECTS)
        # the user (kinematic, no dofs) only: no assistance target for the agent, and
        # no equality constraint but the hands' proximity grasps (inactive)
        assert r.model.nmocap == r.user.model.nbody - 1
        assert all(r.model.equality(i).name.startswith("grasp/") for i in range(r.model.neq))
        assert not data.eq_active.any() and r.assist_wrench(data) == (0.0, 0.0)
        assert r.model.nu == r.agent.model.nu  # only the agent is actuated
        assert np.isfinite(data.qpos).all()


def test_default_and_discomfort_behaviour():
    default = load_scenario("default").behaviour
    assert default.reaction_for("wave").name == "greet"
    assert default.reaction_for("answer_phone").name == "hifi_down"
    assert default.reaction_for("bow").name == "bow_back"
    assert default.reaction_for("clap").name == "keep"
    thesis = load_scenario("discomfort").behaviour
    expected = {"cold": "close_window", "hot": "open_window", "loud": "hifi_down",
                "smell": "cigarette_out", "bright": "close_curtain", "hello": "greet",
                "idle": "keep"}
    assert {g: thesis.reaction_for(g).name for g in expected} == expected
    for name in expected.values():
        reaction = REACTIONS[name]
        assert reaction.object is None or reaction.object in OBJECTS
    with pytest.raises(ScenarioError, match="vocabulary"):
        default.reaction_for("cold")


def test_object_joints_exist_and_states_read_and_set(room: Room):
    data = room.make_data()
    states = room.object_states(data)
    assert set(states) == set(OBJECTS)
    assert room.object_labels(data) == {"window": "closed", "curtain": "open", "hifi": "loud",
                                        "cigarette": "lit", "door": "closed"}
    for name, obj in room.objects.items():
        joint = room.model.joint(obj.joint)
        assert int(joint.qposadr[0]) == obj.qpos_adr
        assert obj.lower < obj.threshold < obj.upper
        for value in (obj.lower, 0.5 * (obj.threshold + obj.upper), obj.upper):
            room.set_object_state(data, name, value)
            assert room.object_states(data)[name] == pytest.approx(value)
        assert room.object_labels(data)[name] == obj.above
        room.set_object_state(data, name, obj.lower)
        assert room.object_labels(data)[name] == obj.below
        with pytest.raises(SimenvError, match=name):
            room.set_object_state(data, name, obj.upper + 1.0)
    with pytest.raises(SimenvError, match="unknown room object"):
        room.set_object_state(data, "fridge", 0.0)
    assert room.objects["hifi"].level(room.objects["hifi"].upper) == pytest.approx(1.0)


def test_scenario_initial_states():
    data = Room("discomfort").make_data()
    assert Room("discomfort").object_labels(data)["window"] == "open"


def _write(tmp_path: Path, edit: tuple[str, str]) -> Path:
    text = load_scenario("default").source
    body = Path(text).read_text()
    old, new = edit
    assert old in body
    path = tmp_path / "bad.toml"
    path.write_text(body.replace(old, new, 1))
    return path


@pytest.mark.parametrize("edit, field", [
    (("offset = -1.0 ", "ofset = -1.0 "), "window.offset"),
    (('wall = "north"', 'wall = "up"'), "window.wall"),
    (("width = 1.0 ", 'width = "wide" '), "window.width"),
    (("offset = -1.0 ", "offset = -2.3 "), "window.offset"),
    (("position = [1.2, 0.6]", "position = [9.0, 0.6]"), "desk.position"),
    (('wave = "greet"', 'wave = "dance"'), "behaviour.reactions.wave"),
    (('bow = "bow_back"', 'sneeze = "bow_back"'), "behaviour.reactions.sneeze"),
    (("volume = 0.8", "volume = 1.8"), "hifi.volume"),
    (("lit = true", "lit = 1"), "cigarette.lit"),
    (("[door]\nwall = \"south\"\noffset = 1.5", "[door]\nwall = \"north\"\noffset = -0.6"),
     "door.offset"),
    (("[agent]\nheight = 1.75", "[agent]"), "agent.height"),
    (("position = [-0.8, -0.6]", "position = [0.9, 0.6]"), "user.position"),
    (("position = [0.75, -0.3]", "position = [1.2, 0.3]"), "hifi.position"),  # in the desk
    (("position = [0.75, -0.3]", "position = [0.3, 0.6]"), "hifi.position"),  # in the chair
])
def test_bad_scenario_field_names_file_and_field(tmp_path: Path, edit, field):
    path = _write(tmp_path, edit)
    with pytest.raises(ScenarioError) as err:
        load_scenario(path)
    assert err.value.field == field
    assert str(path) in str(err.value) and field in str(err.value)


def test_bad_scenario_file(tmp_path: Path):
    path = tmp_path / "broken.toml"
    path.write_text("[room\nsize = 3")
    with pytest.raises(ScenarioError, match="not a valid TOML"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match="bundled"):
        load_scenario(tmp_path / "missing.toml")


def test_seated_agent_is_stable_under_pd(room: Room):
    """One second of mj_step with the PD targets at the seated pose: no blow-up, the body
    stays on the chair and holds its pose."""
    data = room.make_data()
    q0 = data.qpos[room.agent_qpos].copy()
    head = room.agent.keypoint_names.index("head")
    head0 = room.agent_keypoints(data)[head]
    for _ in range(int(round(1.0 / room.model.opt.timestep))):
        mujoco.mj_step(room.model, data)
    assert _warnings(data) == 0
    assert np.isfinite(data.qpos).all()
    q1 = data.qpos[room.agent_qpos]
    assert np.linalg.norm(q1[:3] - q0[:3]) < 0.02  # pelvis stays on the seat
    assert np.abs(q1[7:] - q0[7:]).max() < np.deg2rad(5.0)
    assert np.linalg.norm(room.agent_keypoints(data)[head] - head0) < 0.03
    assert np.abs(data.qvel[room.agent_qvel]).max() < 0.05  # at rest
    seat = room.model.geom("chair/seat").id
    touching = {int(c.geom2) for c in data.contact[:data.ncon] if c.geom1 == seat} | {
        int(c.geom1) for c in data.contact[:data.ncon] if c.geom2 == seat}
    assert touching, "the agent does not sit on the chair"
    # The office chair (rolling, swivelling) holds still under the resting agent.
    for joint, tol in (("chair/roll", 1e-3), ("chair/swivel", np.deg2rad(0.5))):
        assert abs(data.qpos[room.model.joint(joint).qposadr[0]]) < tol, joint


def test_untouched_objects_hold_their_state():
    """Five seconds of simulation leave every object where it was (no creep under load)."""
    room = Room("discomfort")
    data = room.make_data()
    before = room.object_states(data)
    for _ in range(int(round(5.0 / room.model.opt.timestep))):
        mujoco.mj_step(room.model, data)
    after = room.object_states(data)
    for name in OBJECTS:
        assert after[name] == pytest.approx(before[name], abs=1e-4), name


def test_window_opens_when_pushed_and_holds(room: Room):
    """A force on the pane along its slide opens the window through the simulation; a push
    weaker than the sash's friction does not move it, and a released pane stays put."""
    data = room.make_data()
    obj = room.objects["window"]
    pane = room.model.body("window").id
    axis = data.xaxis[room.model.joint(obj.joint).id].copy()
    steps = int(round(0.5 / room.model.opt.timestep))
    data.xfrc_applied[pane, :3] = 3.0 * axis  # below the 5 N friction
    for _ in range(steps):
        mujoco.mj_step(room.model, data)
    assert room.object_labels(data)["window"] == "closed"
    assert room.object_states(data)["window"] < 1e-3
    data.xfrc_applied[pane, :3] = 30.0 * axis
    for _ in range(steps // 2):
        mujoco.mj_step(room.model, data)
    data.xfrc_applied[pane] = 0.0
    for _ in range(steps):  # coasts to a stop under friction and damping
        mujoco.mj_step(room.model, data)
    opened = room.object_states(data)["window"]
    assert room.object_labels(data)["window"] == "open"
    assert opened < obj.upper - 0.05  # stopped by friction, not by the joint limit
    for _ in range(steps):
        mujoco.mj_step(room.model, data)
    assert room.object_states(data)["window"] == pytest.approx(opened, abs=1e-3)
    assert _warnings(data) == 0


def test_user_hand_presses_the_cigarette_out(room: Room):
    """The (kinematic) user's hand is lowered onto the cigarette: contact pushes it into the
    ashtray and it goes out; nothing writes the cigarette's qpos."""
    data = room.make_data()
    m = room.model
    hand = m.body_mocapid[m.body("user/right_hand").id]
    tip = data.geom_xpos[m.geom("cigarette/body").id]
    half = m.geom_size[m.geom("user/right_hand").id]
    offset = -m.geom_pos[m.geom("user/right_hand").id][2] + half[2]  # body origin -> sole
    start = tip[2] + 0.004 + offset + 0.02
    data.mocap_quat[hand] = [1.0, 0.0, 0.0, 0.0]
    assert room.object_labels(data)["cigarette"] == "lit"
    steps = int(round(1.0 / m.opt.timestep))
    for k in range(steps):
        data.mocap_pos[hand] = [tip[0], tip[1], start - 0.03 * k / steps]
        mujoco.mj_step(m, data)
    assert room.object_labels(data)["cigarette"] == "out"
    assert _warnings(data) == 0


def test_user_is_placed_where_the_scenario_says(room: Room):
    data = room.make_data()
    s = room.scenario.user
    pelvis = room.user_keypoints(data)[room.user.keypoint_names.index("pelvis")]
    assert pelvis[:2] == pytest.approx(s.position, abs=1e-6)
    # A trajectory that walks 1 m along its own x keeps its shape, turned to the user's yaw.
    traj = np.tile(room.user.default_qpos(), (2, 1))
    traj[1, 0] += 1.0
    placed = room.place_user(traj)
    step = placed[1, :2] - placed[0, :2]
    yaw = np.deg2rad(s.yaw_deg)
    assert step == pytest.approx([np.cos(yaw), np.sin(yaw)], abs=1e-9)
    with pytest.raises(SimenvError, match="user qpos"):
        room.place_user(np.zeros((2, 5)))


def test_grasp_needs_the_hand_at_the_handle(room: Room):
    data = room.make_data()
    assert not room.set_grasp(data, "right_hand", "window", True)  # seated, far away
    eq = room.model.equality("grasp/right_hand/window").id
    assert not data.eq_active[eq]
    with pytest.raises(SimenvError, match="no grasp"):
        room.set_grasp(data, "right_foot", "window", True)
    assert GRASP_RADIUS < 0.1


def test_greeting_measurement(room: Room):
    """Seated at the desk the agent neither faces the user nor raises a hand; turned to
    face the user with the right arm raised, it greets."""
    data = room.make_data()
    g = room.greeting(data)
    assert not g["success"] and not g["hand_above_shoulder"] and g["facing_deg"] > 30.0
    q = room.seated_pose()
    user = room.user_keypoints(data)[room.user.keypoint_names.index("chest")]
    yaw = np.arctan2(user[1] - q[1], user[0] - q[0])
    q[3:7] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    h = room.agent
    q[h.hinge_qpos[h.joint_names.index("right_upper_arm_flex")]] = np.deg2rad(170.0)
    data.qpos[room.agent_qpos] = q
    mujoco.mj_forward(room.model, data)
    g = room.greeting(data)
    assert g["facing_deg"] < 5.0 and g["hand_above_shoulder"] and g["success"]


def test_cigarette_tip_shows_its_state(room: Room):
    data = room.make_data()
    tip = room.model.geom("cigarette/tip").id
    room.sync_visuals(data)
    glowing = room.model.geom_rgba[tip].copy()
    room.set_object_state(data, "cigarette", room.objects["cigarette"].upper)
    room.sync_visuals(data)
    assert not np.allclose(room.model.geom_rgba[tip], glowing)
