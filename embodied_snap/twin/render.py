"""Fig. 1a: the simulated rig's arm, rendered offscreen from its own MuJoCo model (MUJOCO_GL=egl).

The nominal model (model.NOMINAL) in a preloaded pose: every joint of a section bent by the same
angle toward the commanded bearing, so the image shows the chain, its three sections and the end
effector as the simulator builds them. Colours mark the sections as in Fig. 1b.
"""

from __future__ import annotations

import os

import numpy as np

from .model import N_SEG, NOMINAL, mjcf, seg_names

# S1, S2, S3, end effector (matplotlib's tab10, as the section traces of Fig. 1b)
SECTION_RGBA = ((0.12, 0.47, 0.71, 1), (1.0, 0.5, 0.05, 1), (0.17, 0.63, 0.17, 1), (0.5, 0.5, 0.5, 1))


AZIMUTH = 90.0


def render(bend_deg=(15.0, 30.0, 40.0), width: int = 640, height: int = 800) -> np.ndarray:
    """An RGB image (height, width, 3) of the nominal arm, each section bent by bend_deg in total."""
    os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco loads its GL backend
    import mujoco

    m = mujoco.MjModel.from_xml_string(mjcf(NOMINAL))
    for s, _i, name in seg_names():
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{name}_g")
        m.geom_rgba[gid] = SECTION_RGBA[s - 1]
        m.geom_size[gid][0] *= 1.6  # the capsules are the lattice's core; draw them visibly thick
    m.geom_rgba[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "target_g")][3] = 0.0  # parked far away
    d = mujoco.MjData(m)
    for s, _i, name in seg_names():
        if s <= 3:
            d.qpos[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_z")]] = (
                np.deg2rad(bend_deg[s - 1]) / N_SEG
            )
    mujoco.mj_forward(m, d)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    arm = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for _s, _i, n in seg_names()]
    cam.lookat[:] = (d.xpos[arm].min(0) + d.xpos[arm].max(0)) / 2
    cam.distance = 1.6
    # The free camera orbits a z-up world; the arm hangs along -Y and bends in the XY plane, so
    # look straight down -Z (elevation -90) with the azimuth that puts -Y at the image's bottom.
    cam.azimuth, cam.elevation = AZIMUTH, -90.0
    m.vis.global_.offwidth, m.vis.global_.offheight = max(width, 640), max(height, 480)
    m.vis.headlight.ambient[:] = 0.45
    m.vis.headlight.diffuse[:] = 0.6
    m.vis.rgba.fog[:] = 1.0
    with mujoco.Renderer(m, height, width) as r:
        r.update_scene(d, cam)
        img = r.render().copy()
    img[(img == 0).all(-1)] = 255  # no skybox: a white background instead of black
    return img
