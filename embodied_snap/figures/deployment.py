"""Fig. 7: one successful deployment trial, the rig (top: the recorded motion capture, rendered
offscreen by MuJoCo) and the dynamics model's prediction for the same commands (bottom: the
predicted arm in the same view), at hanging, preload, snap, reach and attachment.

The arm is drawn as capsules through the tracked frames (base, S1, S2, S3 ends) and the cup along
the tip axis; the block as a box at its tracked pose. MuJoCo renders with whatever MUJOCO_GL says
(egl headless); nothing here is the simulated rig's model, so a real rig's recordings draw the same.
"""

from __future__ import annotations

import numpy as np

from .. import bearing as BR
from ..characterize import mocap as M
from ..dynamics import hold
from ..dynamics.model import AXIS, TIP
from ..primitive import release_goals
from ..quat import qrotate, to_matrix
from ..rawformat import TIP_AXIS_LOCAL
from . import style

SCENE = """<mujoco><visual><global offwidth="640" offheight="640"/><headlight ambient=".5 .5 .5"/></visual>
<worldbody><light pos="0 3 1" dir="0 -1 -.3"/>
<geom type="plane" size="3 3 .01" pos="0 {floor} 0" zaxis="0 1 0" rgba=".93 .93 .93 1"/>
<camera name="side" mode="fixed" pos="{cam}" xyaxes="{xy}"/></worldbody></mujoco>"""


def _camera(base: np.ndarray, bearing_deg: float, dist: float = 2.2):
    """A camera looking at the arm from the side of the strike plane (Y up, bearing phi points
    along (cos phi, 0, sin phi))."""
    b = np.deg2rad(bearing_deg)
    side = np.array([-np.sin(b), 0.0, np.cos(b)])  # perpendicular to the strike plane
    centre = base + np.array([0.0, -0.45, 0.0]) + 0.3 * np.array([np.cos(b), 0.0, np.sin(b)])
    cam = centre + dist * side
    x = np.array([np.cos(b), 0.0, np.sin(b)])
    x = -x if np.cross(x, [0.0, 1.0, 0.0]) @ side < 0 else x
    return cam, np.r_[x, 0.0, 1.0, 0.0]


def render(frames: list[dict], base: np.ndarray, bearing_deg: float, size: int = 320) -> list[np.ndarray]:
    """frames: {points (k, 3) lab m: base..tip..cup, block: (pos, quat, half) or None, colour}."""
    import mujoco

    cam, xy = _camera(base, bearing_deg)
    xml = SCENE.format(floor=base[1] - 1.3, cam=" ".join(f"{v:.4f}" for v in cam),
                       xy=" ".join(f"{v:.4f}" for v in xy))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    out = []
    with mujoco.Renderer(m, size, size) as r:
        for f in frames:
            r.update_scene(d, camera="side")
            scn = r.scene
            pts = np.asarray(f["points"], float)
            for a, b in zip(pts[:-1], pts[1:]):
                if scn.ngeom >= scn.maxgeom or not np.all(np.isfinite([a, b])):
                    continue
                g = scn.geoms[scn.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                                    np.asarray(f["colour"], np.float32))
                mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, 0.012, a, b)
                scn.ngeom += 1
            if f.get("block") is not None:
                pos, quat, half = f["block"]
                g = scn.geoms[scn.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_BOX, np.asarray(half, float), np.asarray(pos, float),
                                    to_matrix(np.asarray(quat, float)).ravel(), np.array([.8, .5, .2, 1], np.float32))
                scn.ngeom += 1
            out.append(r.render().copy())
    return out


def plot(top: list[np.ndarray], bottom: list[np.ndarray], titles: list[str], caption: str, pdf: str, png: str) -> None:
    style.setup()
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(top), figsize=(style.TEXT_WIDTH_IN, 3.3))
    for j, (a, b) in enumerate(zip(top, bottom)):
        for row, img in ((0, a), (1, b)):
            ax = axes[row, j]
            ax.imshow(img)
            ax.set_xticks([])
            ax.set_yticks([])
            for s in ax.spines.values():
                s.set_visible(False)
        axes[0, j].set_title(titles[j])
    axes[0, 0].set_ylabel("rig (recorded)")
    axes[1, 0].set_ylabel("dynamics model")
    fig.suptitle(caption, fontsize=7, y=0.02, va="bottom")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    style.save(fig, pdf, png)


MOMENTS = ("hanging", "preload", "snap", "reach", "attachment")


def moments(mc, meta: dict) -> dict:
    """Times (s) of the five moments in a recorded trial: hanging (before the preload), preload
    (its end), snap (peak tip speed after the release began), reach (closest approach of the tip
    to the block), attachment (the observed seal, else 0.1 s after the reach)."""
    lab, t = meta["labels"], mc.t.to_numpy()
    v = M.tip_speed(mc)
    _, t_snap = M.peak(v, t, lab["t_slack"])
    d = np.linalg.norm(M.track(mc, "tip") - M.track(mc, "target"), axis=1)
    d[t < lab["t_slack"]] = np.nan
    t_reach = float(t[int(np.nanargmin(d))]) if np.isfinite(d).any() else t_snap
    t_att = lab.get("t_attach") or t_reach + 0.1
    return dict(hanging=0.5 * lab["t_preload"], preload=lab["t_slack"], snap=t_snap, reach=t_reach,
                attachment=float(t_att))


def recorded_frames(mc, meta: dict, times: dict, ee_m: float) -> list[dict]:
    t = mc.t.to_numpy()
    P = {b: M.track(mc, b) for b in ("base", "s1", "s2", "tip", "target")}
    qt = M.track(mc, "tip", ("qw", "qx", "qy", "qz"))
    qb = M.track(mc, "target", ("qw", "qx", "qy", "qz"))
    half = np.asarray(meta["target"]["size_m"]) / 2
    out = []
    for k in MOMENTS:
        i = int(np.argmin(np.abs(t - times[k])))
        cup = P["tip"][i] + ee_m * qrotate(qt[i], np.array(TIP_AXIS_LOCAL))
        out.append(dict(points=np.stack([P["base"][i], P["s1"][i], P["s2"][i], P["tip"][i], cup]),
                        block=(P["target"][i], qb[i], half), colour=[0.0, 0.45, 0.7, 1.0]))
    return out


def predicted_frames(sim, meta: dict, times: dict, hanging: np.ndarray, ee_m: float) -> list[dict]:
    """The dynamics model's arm for the trial's commands: the hold model's pre-release state, then
    the ensemble-mean rollout (Eq. 4) through the S2 and S1 releases, turned to the commanded
    bearing and placed in the lab with the trial's base pose. `hanging`: the recorded rest frame."""
    prog, lab = meta["program"], meta["labels"]
    act = sim.commands({k: np.array([float(prog[k])]) for k in ("rho1", "rho2", "rho3", "s3", "dphi", "tau")})
    rho = np.stack([act["rho1"], act["rho2"], act["rho3"]], -1)
    U = release_goals(rho, act["s3"], sim.phi0 + act["dphi"], sim.t_u, 0.0, act["tau"], sim.s2_ramp)
    xs, _ = hold.start(sim.bank, act, U[:, :sim.history + 1])
    out = sim.ens.rollout(xs, U[:, 1:], sim.H, parts=(slice(0, 3), slice(3, 6), TIP, AXIS))
    s1, s2, tip, ax = (p[0] for p in out["mean_parts"])
    n = np.asarray(sim.bank["n"], float)
    turn = prog["bearing"] - (sim.phi0 + float(act["dphi"][0]))
    R = to_matrix(np.asarray(meta["base"]["quat"], float))
    B = np.asarray(meta["base"]["pos"], float)
    lab_frame = lambda p: BR.rotate(np.asarray(p, float), turn, n) @ R.T + B  # noqa: E731
    frames = []
    for k in MOMENTS:
        if k == "hanging":
            frames.append(dict(points=hanging, block=None, colour=[0.84, 0.37, 0.0, 1.0]))
            continue
        if k == "preload":
            x = xs[0, -1].astype(float)
            p = [x[0:3], x[3:6], x[6:9], x[6:9] + ee_m * x[9:12] / np.linalg.norm(x[9:12])]
        else:
            j = int(np.clip(round((times[k] - lab["t_s2"] - sim.anchor_s) / sim.dt), 0, sim.H))
            p = [s1[j], s2[j], tip[j], tip[j] + ee_m * ax[j] / np.linalg.norm(ax[j])]
        frames.append(dict(points=np.vstack([B[None], lab_frame(np.stack(p))]), block=None,
                           colour=[0.84, 0.37, 0.0, 1.0]))
    return frames


def empty(pdf: str, png: str) -> None:
    """Fig. 7 when no trial completed (results/deployment/summary.json says why)."""
    style.setup()
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(style.TEXT_WIDTH_IN, 1.0))
    ax.axis("off")
    ax.text(0.5, 0.5, "no complete deployment trial (raw_data/deployment/aborted.json)", ha="center")
    style.save(fig, pdf, png)
