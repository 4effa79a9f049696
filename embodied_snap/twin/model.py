"""The arm as a MuJoCo model: nominal parameters and the MJCF they compile to.

A rigid-segment chain hanging from the base along -Y (gravity -Y, lab frame of the rig format).
Each section is `N_SEG` rigid segments joined by elastic, damped 2-DOF joints (two hinges: about
local Z bends toward +X, about local X bends toward -Z). The 150 mm end effector is two softer
segments. Nine cables are fixed tendons, linear in the joint angles exactly as the paper's Eq. 1
(lever d_p per section, summed over every section the cable traverses), each driven by a
pull-only position actuator: force = kp*(free_length - length) - kv*rate, clamped to [-F_max, 0],
so a cable pulls when taut and does nothing when slack.
"""

from __future__ import annotations

import functools

import numpy as np

K_TICK = 15.8e-6  # m of tendon per servo tick (paper III-A)
N_SEG = 3  # rigid segments per section
N_EE = 2  # segments of the end effector

# Nominal rig parameters. `truth.py` perturbs the per-session ones; everything here is SI.
NOMINAL = dict(
    sec_len=(0.324, 0.230, 0.176),
    ee_len=0.150,
    sec_radius=(0.030, 0.024, 0.019),  # tapered lattice, outer radius (geometry, inertia)
    ee_radius=0.016,
    sec_mass=(0.120, 0.070, 0.045),  # kg per section (TPU lattice + PLA connector)
    ee_mass=0.060,  # Ecoflex end effector with cups
    lever_ticks_per_rad=(2351.0, 1411.0, 1390.0),  # d_p / k (paper Eq. 1)
    sec_stiffness=(0.596, 0.167, 0.168),  # N m / rad, section-level bending stiffness (identified)
    ee_stiffness=0.101,
    damping_ratio=0.0253,  # of each joint's own critical damping (identified; TPU lattice rings)
    drag=0.26,  # MuJoCo viscosity, Pa s: lattice losses and air drag on the bodies (identified)
    frictionloss=0.004,  # N m, per joint: lattice hysteresis (loading and unloading differ)
    cable_kp=4000.0,  # N/m, series compliance of cable, spool and lattice (identified with the latch)
    cable_kv=8.0,  # N s/m
    cable_fmax=300.0,  # N, servo stall torque / spool radius
    # The mount (clamp, servo bracket and nine servos) hangs on the lab frame, which yields when an
    # operator holds it: three translations on a spring-damper (chosen, not fitted: a 1 kg mount,
    # 8 N/mm, 30 % of critical damping; a 10-40 N hand moves it 1-5 mm).
    mount_mass=1.0,  # kg
    mount_stiffness=8000.0,  # N/m per axis
    mount_damping_ratio=0.3,
)

BODY_NAMES = ("s1", "s2", "tip")  # tracked distal ends of S1, S2, S3
PROXIMAL = "seg1_0"  # the proximal S1 segment, where a hand on the mount also grips the arm


def seg_names():
    """(section, index, body name) for every arm segment; section 4 is the end effector."""
    out = []
    for s in range(1, 4):
        for i in range(N_SEG):
            out.append((s, i, f"seg{s}_{i}"))
    for i in range(N_EE):
        out.append((4, i, f"ee_{i}"))
    return out


def mjcf(p: dict) -> str:
    segs = seg_names()
    lens, rads, masses, kjs = [], [], [], []
    for s, _i, _n in segs:
        if s <= 3:
            lens.append(p["sec_len"][s - 1] / N_SEG)
            rads.append(p["sec_radius"][s - 1])
            masses.append(p["sec_mass"][s - 1] / N_SEG)
            kjs.append(p["sec_stiffness"][s - 1] * N_SEG)
        else:
            lens.append(p["ee_len"] / N_EE)
            rads.append(p["ee_radius"])
            masses.append(p["ee_mass"] / N_EE)
            kjs.append(p["ee_stiffness"] * N_EE)
    lens, masses = np.array(lens), np.array(masses)
    # Inertia seen by each joint: everything distal, about the joint (straight arm).
    cum = np.concatenate([[0.0], np.cumsum(lens)])
    inert = []
    for j in range(len(segs)):
        mid = (cum[j:-1] + cum[j + 1 :]) / 2 - cum[j]
        inert.append(float(np.sum(masses[j:] * mid**2)))
    body = ""
    closing = ""
    for j, (s, i, name) in enumerate(segs):
        L, r, m, kj = lens[j], rads[j], masses[j], kjs[j]
        c = 2 * np.sqrt(kj * inert[j]) * p["damping_ratio"]
        pos = "0 0 0" if j == 0 else f"0 {-lens[j - 1]:.6f} 0"
        body += (
            f'<body name="{name}" pos="{pos}">'
            f'<joint name="{name}_z" axis="0 0 1" stiffness="{kj:.6g}" damping="{c:.6g}" '
            f'frictionloss="{p["frictionloss"]:.6g}"/>'
            f'<joint name="{name}_x" axis="1 0 0" stiffness="{kj:.6g}" damping="{c:.6g}" '
            f'frictionloss="{p["frictionloss"]:.6g}"/>'
            f'<geom name="{name}_g" type="capsule" fromto="0 0 0 0 {-L:.6f} 0" size="{r * 0.5:.4f}" '
            f'mass="{m:.6g}" contype="0" conaffinity="0"/>'
        )
        closing += "</body>"
        if s <= 3 and i == N_SEG - 1:
            # the distal end of a section: the tracked marker frame
            body += f'<site name="{BODY_NAMES[s - 1]}" pos="0 {-L:.6f} 0"/>'
        if s == 4 and i == N_EE - 1:
            # cup face: contacts the target block (a 2 cm sphere: simulated hardware, not a protocol value)
            body += (
                f'<site name="cup" pos="0 {-L:.6f} 0"/>'
                f'<geom name="cup_g" type="sphere" pos="0 {-L:.6f} 0" size="0.02" mass="0.0" '
                f'contype="1" conaffinity="1" condim="3" friction="1.0"/>'
            )
    body += closing
    # the mount: three slides on a spring-damper, the y spring preloaded so the loaded mount rests at 0
    km, mm = p["mount_stiffness"], p["mount_mass"]
    cm = 2 * p["mount_damping_ratio"] * np.sqrt(km * (mm + masses.sum()))
    sag = (mm + masses.sum()) * 9.81 / km
    mount = "".join(
        f'<joint name="mount_{ax}" type="slide" axis="{v}" stiffness="{km:.6g}" damping="{cm:.6g}" '
        f'springref="{ref:.8f}"/>'
        for ax, v, ref in (("x", "1 0 0", 0.0), ("y", "0 1 0", sag), ("z", "0 0 1", 0.0))
    )
    mount += f'<geom name="mount_g" type="sphere" size="0.03" mass="{mm:.6g}" contype="0" conaffinity="0"/>'
    mount += '<site name="mount" pos="0 0 0"/>'
    tendons, acts = "", ""
    for s in range(1, 4):
        for k in range(1, 4):
            a = np.deg2rad(120.0 * (k - 1))
            coefs = ""
            for ss, _i, name in segs:
                if ss > s:
                    continue
                # every joint of section ss has the section's lever d_p, so the cable sees d_p
                # times the section bend (sum of its joints' bends): Eq. 1
                d = p["lever_ticks_per_rad"][ss - 1] * K_TICK
                # shortening = d (b_x cos a + b_z sin a), b_x = q_z, b_z = -q_x
                coefs += f'<joint joint="{name}_z" coef="{-d * np.cos(a):.8f}"/>'
                coefs += f'<joint joint="{name}_x" coef="{d * np.sin(a):.8f}"/>'
            tname = f"cable{s}{k}"
            tendons += f'<fixed name="{tname}">{coefs}</fixed>'
            kp, kv = p["cable_kp"], p["cable_kv"]
            acts += (
                f'<general name="servo{3 * (s - 1) + k}" tendon="{tname}" gainprm="{kp}" '
                f'biasprm="0 {-kp} {-kv}" biastype="affine" forcelimited="true" '
                f'forcerange="{-p["cable_fmax"]} 0" ctrllimited="false"/>'
            )
    eqs = ""
    for s, _i, name in segs:
        if s in (1, 2, 3):  # the fold latch: sim.py switches on S2+S3 (or all)
            for ax in "zx":
                eqs += f'<joint name="latch_{name}_{ax}" joint1="{name}_{ax}" active="false" solref="0.01 1"/>'
    eqs += f'<connect name="seal" body1="ee_{N_EE - 1}" body2="target" anchor="0 0 0" active="false"/>'
    target = (
        '<body name="target" mocap="true" pos="0 -5 0">'
        '<geom name="target_g" type="box" size="0.05 0.03 0.015" contype="1" conaffinity="1" condim="3" '
        'friction="1.0"/></body>'
    )
    if "block_mass" in p:
        # deployment: the block is a free body, held on its support by a weld to the world (sim.Arm)
        target = (
            '<body name="target" pos="0 -5 0"><freejoint name="target_free"/>'
            f'<geom name="target_g" type="box" size="0.05 0.03 0.015" mass="{p["block_mass"]:.6g}" contype="1" '
            'conaffinity="1" condim="3" friction="1.0"/></body>'
        )
        eqs += '<weld name="support" body1="target" active="false"/>'
    # Euler integrates joint damping implicitly; implicitfast would also differentiate the
    # viscous drag every step (3x slower) for no change: halving dt moves tip speeds < 0.5 %.
    return f"""<mujoco model="embodied_snap_arm">
<compiler angle="radian"/>
<option timestep="0.001" gravity="0 -9.81 0" integrator="Euler" viscosity="{p.get("drag", 0.0)}"/>
<worldbody>
<body name="base" pos="0 0 0">{mount}{body}</body>
{target}
</worldbody>
<tendon>{tendons}</tendon>
<actuator>{acts}</actuator>
<equality>{eqs}</equality>
</mujoco>"""


@functools.lru_cache(maxsize=32)
def _compiled(key: tuple):
    import mujoco

    p = dict(key)
    return mujoco.MjModel.from_xml_string(mjcf(p))


def build(p: dict, dt: float = 0.001):
    """A private MjModel for parameters p (compiled once per distinct p, then deep-copied: a
    trial edits its copy's latch and seal equalities)."""
    import copy

    key = tuple(sorted((k, tuple(v) if isinstance(v, (list, tuple)) else v) for k, v in p.items()))
    m = copy.deepcopy(_compiled(key))
    m.opt.timestep = dt
    return m
