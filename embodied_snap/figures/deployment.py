"""Fig. 7: one successful deployment trial, the rig (top: the recorded motion capture, rendered
offscreen by MuJoCo) and the dynamics model's prediction for the same commands (bottom: the
predicted arm in the same view), at hanging, preload, snap, reach and attachment.

Both rows draw the arm the same way from what both know, the tracked frames (base, S1, S2, S3
ends): each section a constant-curvature arc leaving its proximal end along the arc before it (the
base along the hanging axis) and ending at its tracked distal end, tapering from S1 to S3; the cup
at the end effector's length along the tip axis; the block as a box at its tracked pose. Nothing
here is the simulated rig's model, so a real rig's recordings draw the same. MuJoCo renders with
whatever MUJOCO_GL says (egl headless).
"""

from __future__ import annotations

import numpy as np

from .. import bearing as BR
from ..characterize import mocap as M
from ..cup import cup_from_pose
from ..dynamics import hold
from ..dynamics.model import AXIS, TIP
from ..primitive import release_goals
from ..quat import qrotate, to_matrix
from ..rawformat import TIP_AXIS_LOCAL
from . import style

SCENE = """<mujoco><visual><global offwidth="640" offheight="640"/><headlight ambient=".55 .55 .55"/></visual>
<asset><texture type="skybox" builtin="flat" rgb1="1 1 1" rgb2="1 1 1" width="8" height="8"/></asset>
<worldbody><light pos="0 3 1" dir="0 -1 -.3"/>
<camera name="side" mode="fixed" pos="{cam}" xyaxes="{xy}" fovy="40"/></worldbody></mujoco>"""
RADIUS_M = (0.018, 0.014, 0.010)  # drawn section radii, S1..S3 (the lattice tapers)
CUP_R = 0.02  # m, drawn cup radius


def arc(a: np.ndarray, tangent: np.ndarray, b: np.ndarray, n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The circular arc from a, leaving along `tangent`, to b: (n + 1, 3) points and the tangent at b.
    A straight segment when b lies along the tangent."""
    t = tangent / np.linalg.norm(tangent)
    c = b - a
    L = np.linalg.norm(c)
    perp = c - (c @ t) * t
    if L < 1e-9 or np.linalg.norm(perp) < 1e-6 * L:
        return a + np.linspace(0, 1, n + 1)[:, None] * c, (c / L if L > 1e-9 else t)
    u = perp / np.linalg.norm(perp)
    theta = np.arctan2(c @ u, c @ t)  # angle between the tangent and the chord; the arc turns 2 theta
    R = L / (2 * np.sin(theta))
    phi = np.linspace(0, 2 * theta, n + 1)[:, None]
    pts = a + R * np.sin(phi) * t + R * (1 - np.cos(phi)) * u
    return pts, np.cos(2 * theta) * t + np.sin(2 * theta) * u


def arm_curve(points: np.ndarray, axis0: np.ndarray) -> list[np.ndarray]:
    """points: base, S1, S2, S3 ends (4, 3); axis0: the hanging axis at the base. One polyline per
    section, each arc leaving along the one before."""
    out, t = [], np.asarray(axis0, float)
    for a, b in zip(points[:-1], points[1:]):
        pts, t = arc(np.asarray(a, float), t, np.asarray(b, float))
        out.append(pts)
    return out


def _camera(base: np.ndarray, bearing_deg: float, dist: float = 1.6):
    """A camera looking at the arm from the side of the strike plane (Y up, bearing phi points
    along (cos phi, 0, sin phi))."""
    b = np.deg2rad(bearing_deg)
    side = np.array([-np.sin(b), 0.0, np.cos(b)])  # perpendicular to the strike plane
    centre = base + np.array([0.0, -0.45, 0.0]) + 0.25 * np.array([np.cos(b), 0.0, np.sin(b)])
    cam = centre + dist * side
    x = np.array([np.cos(b), 0.0, np.sin(b)])
    x = -x if np.cross(x, [0.0, 1.0, 0.0]) @ side < 0 else x
    return cam, np.r_[x, 0.0, 1.0, 0.0]


def _geom(scn, kind, size, pos, mat, rgba) -> None:
    import mujoco

    if scn.ngeom >= scn.maxgeom:
        return
    mujoco.mjv_initGeom(scn.geoms[scn.ngeom], kind, np.asarray(size, float), np.asarray(pos, float),
                        np.asarray(mat, float).ravel(), np.asarray(rgba, np.float32))
    scn.ngeom += 1


def _capsule(scn, a, b, r, rgba) -> None:
    import mujoco

    if scn.ngeom >= scn.maxgeom or not np.all(np.isfinite([a, b])):
        return
    g = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                        np.asarray(rgba, np.float32))
    mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, r, a, b)
    scn.ngeom += 1


def render(frames: list[dict], base: np.ndarray, bearing_deg: float, axis0: np.ndarray,
           size: int = 320) -> list[np.ndarray]:
    """frames: {points (5, 3) lab m: base, S1, S2, S3 ends, cup; block: (pos, quat, half) or None,
    colour}. axis0: the hanging axis (lab) the arm leaves its base along."""
    import mujoco

    cam, xy = _camera(base, bearing_deg)
    xml = SCENE.format(cam=" ".join(f"{v:.4f}" for v in cam),
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
            rgba = np.asarray(f["colour"], float)
            if np.all(np.isfinite(pts)):
                for s, seg in enumerate(arm_curve(pts[:4], axis0)):
                    shade = np.r_[rgba[:3] * (0.75 + 0.125 * s), rgba[3]]  # S1 darkest
                    for a, b in zip(seg[:-1], seg[1:]):
                        _capsule(scn, a, b, RADIUS_M[s], shade)
                _capsule(scn, pts[3], pts[4], 0.006, [0.3, 0.3, 0.3, 1.0])  # the end effector
                ax = (pts[4] - pts[3]) / np.linalg.norm(pts[4] - pts[3])
                z = np.cross(ax, [1.0, 0.0, 0.0])
                z = z / np.linalg.norm(z) if np.linalg.norm(z) > 1e-6 else np.array([0.0, 0.0, 1.0])
                _geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [CUP_R, 0.006, 0], pts[4],
                      np.stack([z, np.cross(ax, z), ax], 1), [0.15, 0.15, 0.15, 1.0])  # the cup, axis along the tip
            if f.get("block") is not None:
                pos, quat, half = f["block"]
                _geom(scn, mujoco.mjtGeom.mjGEOM_BOX, half, pos, to_matrix(np.asarray(quat, float)),
                      [0.8, 0.5, 0.2, 1.0])
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
                s.set(visible=True, color="0.85")  # a light frame per panel
        axes[0, j].set_title(titles[j])
    axes[0, 0].set_ylabel("rig (recorded)")
    axes[1, 0].set_ylabel("dynamics model")
    fig.suptitle(caption, fontsize=7, y=0.02, va="bottom")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    style.save(fig, pdf, png)


MOMENTS = ("hanging", "preload", "snap", "reach", "attachment")


def moments(mc, meta: dict, ee_m: float, max_gap_s: float) -> dict:
    """Times (s) of the five moments in a recorded trial, in this order: hanging (halfway to the
    preload), preload (its end: S3 slackened, the fold latched), reach (the cup's closest approach
    to the block after the S1 release, up to the observed seal), snap (mid-strike: the cup first
    halfway from where it was at the S1 release to that closest approach), attachment (the block
    held on the cup: the carry's start, else 0.3 s after the seal; without a seal 0.3 s after the
    reach). Raises ValueError when they are not in that order."""
    lab, t = meta["labels"], mc.t.to_numpy()
    cup = cup_from_pose(M.track(mc, "tip", max_gap_s=max_gap_s),
                        M.track(mc, "tip", ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s), ee_m)
    d = np.linalg.norm(cup - M.track(mc, "target", max_gap_s=max_gap_s), axis=1)
    t_att = lab.get("t_attach")
    after = t >= lab["t_s1"]
    d_after = np.where(after & (t <= (t_att if t_att is not None else lab["t_s1"] + 1.0)), d, np.nan)
    if not np.isfinite(d_after).any():
        raise ValueError(f"group {meta['group_id']}: cup or block untracked after the S1 release")
    k_reach = int(np.nanargmin(d_after))
    k_rel = int(np.flatnonzero(after & np.isfinite(d))[0])
    half = 0.5 * (d[k_rel] + d[k_reach])
    k_snap = k_rel + int(np.argmax(~(d[k_rel:k_reach + 1] > half)))  # first at or inside half the way
    t_hold = lab.get("t_carry") or (t_att if t_att is not None else float(t[k_reach])) + 0.3
    out = dict(hanging=0.5 * lab["t_preload"], preload=lab["t_slack"], snap=float(t[k_snap]),
               reach=float(t[k_reach]), attachment=float(t_hold))
    ts = list(out.values())
    if not all(a < b for a, b in zip(ts[:-1], ts[1:])):
        raise ValueError(f"group {meta['group_id']}: moments out of order {out}")
    return out


def recorded_frames(mc, meta: dict, times: dict, ee_m: float, max_gap_s: float) -> list[dict]:
    t = mc.t.to_numpy()
    P = {b: M.track(mc, b, max_gap_s=max_gap_s) for b in ("base", "s1", "s2", "tip", "target")}
    qt = M.track(mc, "tip", ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s)
    qb = M.track(mc, "target", ("qw", "qx", "qy", "qz"), max_gap_s=max_gap_s)
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


def empty(pdf: str, png: str, why: str = "no complete deployment trial (raw_data/deployment/aborted.json)") -> None:
    """Fig. 7 when there is no trial to draw, saying why."""
    style.setup()
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(style.TEXT_WIDTH_IN, 1.0))
    ax.axis("off")
    ax.text(0.5, 0.5, why, ha="center")
    style.save(fig, pdf, png)
