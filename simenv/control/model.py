"""The planning model: the humanoid plus the sensors the planner's cost reads.

``mujoco.rollout`` returns, per sample and step, the state and the sensor
readings. Reading keypoints from the state would need forward kinematics of
every rolled-out state in Python; sensors compute them inside MuJoCo, in the
rollout threads. :func:`planning_model` adds to a copy of the humanoid's spec:

* one ``framepos`` sensor per keypoint site (world position, metres), K x 3;
* ``subtreecom`` of the pelvis: whole-body centre of mass (metres), 3;
* ``subtreelinvel`` of the pelvis: its velocity (m/s), 3;
* ``framequat`` of the upper trunk (:data:`TRUNK_BODY`): its world orientation
  as a unit quaternion ``(w, x, y, z)``, 4.

Sensors do not change the dynamics, so the same model both plans and is
simulated (the controller never plans on a model other than the one it
drives, except with ``timestep_factor > 1``: the same body integrated with a
coarser step, a cheaper but inexact model of the simulated one).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from simenv.body.humanoid import Humanoid
from simenv.core.errors import PhysicsError

#: The upper-trunk body whose orientation the planner tracks: the shoulders
#: and the neck hang from it.
TRUNK_BODY = "chest"


@dataclass(frozen=True)
class SensorLayout:
    """Where each quantity sits in a row of ``sensordata``.

    Attributes:
        keypoints: slice of the K x 3 keypoint positions (reshape to (K, 3)).
        com: slice of the centre of mass (3). com_vel: slice of its velocity (3).
        trunk: slice of the upper trunk's world quaternion ``(w, x, y, z)`` (4).
        n_keypoints: K. size: total sensor values per step.
    """

    keypoints: slice
    com: slice
    com_vel: slice
    trunk: slice
    n_keypoints: int
    size: int


def planning_model(humanoid: Humanoid, timestep_factor: int = 1, gain_scale: float = 1.0
                   ) -> tuple[mujoco.MjModel, SensorLayout]:
    """The humanoid's model with the planner's sensors (module docstring).

    Args:
        humanoid: the body to simulate (its spec is copied, never modified).
        timestep_factor: integer multiple of the humanoid's timestep to
            integrate with (1: the simulated model itself).

    Raises:
        PhysicsError: ``timestep_factor`` below 1 or the humanoid's spec already
            holds sensors (the layout would not start at 0).
    """
    if int(timestep_factor) != timestep_factor or timestep_factor < 1:
        raise PhysicsError(f"timestep_factor must be an integer >= 1; got {timestep_factor}",
                           field="timestep_factor")
    spec = humanoid.spec.copy()
    if len(spec.sensors):
        raise PhysicsError(f"the humanoid already has {len(spec.sensors)} sensors",
                           field="humanoid")
    spec.option.timestep = humanoid.model.opt.timestep * int(timestep_factor)
    site_names = [humanoid.model.site(i).name for i in humanoid.site_ids]
    for name in site_names:
        s = spec.add_sensor()
        s.name = f"kp_{name}"
        s.type = mujoco.mjtSensor.mjSENS_FRAMEPOS
        s.objtype = mujoco.mjtObj.mjOBJ_SITE
        s.objname = name
    root = humanoid.model.body(1).name
    for sensor_type, label in ((mujoco.mjtSensor.mjSENS_SUBTREECOM, "com"),
                               (mujoco.mjtSensor.mjSENS_SUBTREELINVEL, "com_vel")):
        s = spec.add_sensor()
        s.name = label
        s.type = sensor_type
        s.objtype = mujoco.mjtObj.mjOBJ_BODY
        s.objname = root
    s = spec.add_sensor()
    s.name = "trunk_quat"
    s.type = mujoco.mjtSensor.mjSENS_FRAMEQUAT
    s.objtype = mujoco.mjtObj.mjOBJ_XBODY  # the body frame (mjOBJ_BODY: its inertia frame)
    s.objname = TRUNK_BODY
    model = spec.compile()
    model.actuator_gainprm[:, 0] *= gain_scale
    model.actuator_biasprm[:, 1:3] *= gain_scale
    K = len(site_names)
    layout = SensorLayout(keypoints=slice(0, 3 * K), com=slice(3 * K, 3 * K + 3),
                          com_vel=slice(3 * K + 3, 3 * K + 6),
                          trunk=slice(3 * K + 6, 3 * K + 10), n_keypoints=K,
                          size=int(model.nsensordata))
    assert layout.size == 3 * K + 10
    return model, layout


def keypoints_of(sensordata: np.ndarray, layout: SensorLayout) -> np.ndarray:
    """(..., K, 3) keypoint positions from (..., size) sensor rows."""
    kp = sensordata[..., layout.keypoints]
    return kp.reshape(kp.shape[:-1] + (layout.n_keypoints, 3))


def root_dofs(model: mujoco.MjModel) -> np.ndarray:
    """The free root joint's dof indices (6,)."""
    return np.arange(model.jnt_dofadr[0], model.jnt_dofadr[0] + 6)
