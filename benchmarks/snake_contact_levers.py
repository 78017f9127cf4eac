"""T² Snake-3: what sets the contact forces' trend with the head's height (Tables IV-V), in closed form.

    python benchmarks/snake_contact_levers.py [OVERSHOOT_MM] [--table PATH] [--twist C] [--sim [POSTURE ...]]

The paper's f_x and f_y both scale about as z_h^-2 over (i)-(iii) and (iv)-(vi), the law
of a push resisted by a rotational spring whose axis lies at a height h0 below the
contact: the lever is z_h - h0, so f = K delta / (z_h - h0)^2 and the exponent is
n = -2 z_h / (z_h - h0), i.e. h0 = z_h (1 + 2 / n). This prints h0 for the paper's and
our means: those of a `snake.contact` table (--table, default
results/snake_contact/table.parquet, what `jaxloco sweep snake_contact` writes in the
current directory), or where there is none the defaults' means typed in below (measured
on 8 Dec 2026); and then, for each posture of the contact experiment on the no-skid model
(`contact.head_posture`, rigid base), each head-part joint's lever along each push
(|axis x (contact - joint)| . push [m]) and the static force of a position push that
overshoots by OVERSHOOT_MM (default: `contact.OVERSHOOT`) against the head servos'
stiffness alone (`model.KP`): f = delta / sum_i(lever_i^2 / KP). That is an upper bound
on the servo-limited force (the base, the wheels and the contact give too), and its
trend is the head part's geometry.

With --sim (about 15 s; default postures i ii iii iv vi) it runs the three pushes of
each posture in MuJoCo (`contact.contact_scenario`, the defaults, one trial without
jitter; --twist C: the base's twist compliance [rad/(N m)], 0 a rigid base, default
`contact.TWIST_COMPLIANCE`) and splits the give along the push at the force's peak, counted from the push's
start: the head target (`kinsim.Target`'s smooth step) less the head, into the head-part
joints' share (the head the commanded joints would put on the measured base less the
measured head) and the rest, the base's (the base where it is, not where the
feedforward controller put it), with link 7's motion over the push.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

import jax.numpy as jnp  # noqa: E402

from jaxloco.robots.snake import contact, kinematics, model  # noqa: E402
from jaxloco.robots.snake import params as sp  # noqa: E402

# `jaxloco sweep snake_contact` at the defaults (the twisting base), mean of 5 trials (docs/snake.md, 8 Dec 2026)
OURS = {"i": (15.6, 9.8, 15.7), "ii": (23.7, 9.4, 11.1), "iii": (29.9, 9.1, 9.3),
        "iv": (15.2, 9.9, 15.8), "v": (23.2, 9.4, 11.1), "vi": (29.4, 9.1, 9.3)}
CONTACT_POINT = ("front", "mid", "mid")  # where the gripper meets the plate per push (`contact.plate_pose`)


def axis_heights(means: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """h0 = z_h (1 + 2 / n) [m] at the middle height (0.35 m) for f_x, f_y per base."""
    return {base: 0.35 * (1.0 + 2.0 / n[:2]) for base, n in contact.height_exponents(means).items()}


def levers(name: str) -> tuple[np.ndarray, float]:
    """(levers (3 pushes, 6 head-part joints) [m], head height [m]) of a posture."""
    z_h, y_h, base = contact.POSTURES[name]
    phi, base_pose = contact.head_posture(z_h, y_h, base)
    head = contact.kinematic_head(phi, base_pose)
    joints = kinematics.full_joint_angles(jnp.asarray(phi))
    R, p = (np.asarray(a) for a in kinematics.link_frames(jnp.asarray(head), joints))
    back, front = contact.gripper_segment(head)
    points = {"front": front, "mid": 0.5 * (back + front)}
    out = np.zeros((3, sp.N_H))
    for d, push in enumerate(contact.PUSH):
        point = points[CONTACT_POINT[d]]
        for k in range(sp.N_H):  # joint k sits at the front of link k + 2 (index k + 1)
            axis = R[k + 1][:, 1] if sp.JOINT_IS_PITCH[k] else -R[k + 1][:, 2]
            out[d, k] = np.cross(axis, point - p[k + 1]) @ push
    return out, float(head[2])


def give_at_peak(postures: list[str], twist: float = contact.TWIST_COMPLIANCE) -> None:
    """Print where each push's give went at its force peak (module docstring, --sim),
    on a base of twist compliance `twist` [rad/(N m)]."""
    from jaxloco.robots.snake import experiments
    from jaxloco.sim.rollout import Simulator

    defaults = {p.name: p.default for p in contact.PARAMS}  # the contact experiment's
    ramp, hold, settle = (float(defaults[k]) for k in ("ramp", "hold", "settle"))
    n = len(postures)
    sim = Simulator(nthread=2)
    heads = contact.settled_heads(np.array(postures), ramp, hold, settle, sim, twist_compliance=twist)
    params = contact.push_params(np.array(postures), np.full(n, contact.FLOOR_MU), np.zeros(n),
                                 np.full(n, contact.OVERSHOOT), ramp, settle, heads)
    params["key"] = np.zeros((3 * n, 2), np.uint32)
    scenario = contact.contact_scenario(ramp, hold, settle, twist_compliance=twist)
    rec = {k: np.asarray(v) for k, v in sim.run(scenario, params).records.items()}
    t = (np.arange(rec["head"].shape[1]) + 1) * contact.CONTROL_DT
    t0 = settle + experiments.T_START
    i0, i_end = np.searchsorted(t, t0), np.searchsorted(t, t0 + ramp + 0.5)
    tau = np.clip((t - t0) / ramp, 0.0, 1.0)
    step = tau - np.sin(2 * np.pi * tau) / (2 * np.pi)  # kinsim.Target's smooth step
    travel = contact.PLATE_GAP + contact.OVERSHOOT
    base = f"twist compliance {twist:g} rad/(N m)" if twist > 0 else "a rigid base"
    print(f"\ngive along the push at the force peak, from the push's start [mm] (MuJoCo, "
          f"{contact.OVERSHOOT * 1e3:g} mm overshoot, {base}); link 7's motion over the push")
    print(f"{'posture':8s} push  peak [N]  give  joints  base   link7 dx dy [mm]  droll dyaw [rad]")
    for i, name in enumerate(postures):
        w0 = contact.kinematic_head(*contact.head_posture(*contact.POSTURES[name]))[:3]
        for d, push in enumerate(contact.PUSH):
            j = 3 * i + d
            force = np.convolve(rec["fixture"][j, :, 0], np.ones(contact.SMOOTH_RECORDS) / contact.SMOOTH_RECORDS,
                                mode="same")
            ip = int(np.argmax(force[:i_end]))
            head, base = rec["head"][j, :, :3], rec["base"][j]

            def commanded(k):  # the head the commanded joints put on the measured base
                return contact.kinematic_head(rec["phi_cmd"][j, k], base[k, [0, 1, 5]])[:3]

            def target(k):
                return w0 + push * travel * step[k]

            give = ((target(ip) - head[ip]) - (target(i0) - head[i0])) @ push
            joints = ((commanded(ip) - head[ip]) - (commanded(i0) - head[i0])) @ push
            moved = base[ip] - base[i0]
            lead = f"({name})" if d == 0 else ""
            print(f"{lead:8s} f_{contact.DIRECTIONS[d]}   {force[ip]:7.1f}  {give * 1e3:5.1f}  {joints * 1e3:5.1f}  "
                  f"{(give - joints) * 1e3:5.1f}   {moved[0] * 1e3:6.1f} {moved[1] * 1e3:5.1f}      "
                  f"{moved[3]:+.4f} {moved[5]:+.4f}")


def main(argv: list[str]) -> None:
    sim_postures, twist = None, contact.TWIST_COMPLIANCE
    if "--twist" in argv:
        at = argv.index("--twist")
        twist, argv = float(argv[at + 1]), argv[:at] + argv[at + 2:]
    if "--sim" in argv:
        at = argv.index("--sim")
        sim_postures, argv = argv[at + 1:] or ["i", "ii", "iii", "iv", "vi"], argv[:at]
    table_path = Path("results/snake_contact/table.parquet")
    if "--table" in argv:
        at = argv.index("--table")
        table_path, argv = Path(argv[at + 1]), argv[:at] + argv[at + 2:]
    delta = float(argv[0]) / 1e3 if argv else contact.OVERSHOOT
    paper = contact.PAPER_MEANS
    if table_path.is_file():
        from jaxloco.sweep.summary import read_table

        ours, source = contact.posture_means(read_table(table_path)[0]), str(table_path)
    else:
        ours, source = {k: np.array(v) for k, v in OURS.items()}, "the defaults' means of 8 Dec 2026 (no table)"
    print(f"ours: {source}")
    print("force ~ z_h^n over (i)-(iii) / (iv)-(vi); h0: the axis height that exponent implies [m]")
    for label, means in (("paper", paper), ("ours", ours)):
        ex, h0 = contact.height_exponents(means), axis_heights(means)
        for base in ex:
            print(f"  {label:5s} {base:8s} n f_x {ex[base][0]:+.2f} f_y {ex[base][1]:+.2f} f_z {ex[base][2]:+.2f}"
                  f"   h0 f_x {h0[base][0]:+.3f} f_y {h0[base][1]:+.3f}")
    print(f"\nhead-part joint levers [m] and the static force of a {delta * 1e3:g} mm push against KP = "
          f"{model.KP:g} N m/rad alone (rigid base) [N]; the paper's mean beside")
    names = [sp.JOINT_NAMES[k] for k in range(sp.N_H)]
    print(f"{'posture':8s} {'z_h':>5s}  push  " + " ".join(f"{n:>7s}" for n in names) + "   static  paper")
    for name in contact.POSTURE_NAMES:
        lv, z = levers(name)
        for d, push in enumerate(contact.DIRECTIONS):
            force = delta / np.sum(lv[d] ** 2 / model.KP)
            lead = f"({name})" if d == 0 else ""
            zc = f"{z:5.2f}" if d == 0 else " " * 5
            print(f"{lead:8s} {zc}  f_{push}   " + " ".join(f"{v:+7.3f}" for v in lv[d])
                  + f"   {force:6.1f}  {contact.PAPER_FORCES[name][d][0]:5.1f}")
    if sim_postures:
        give_at_peak(sim_postures, twist)


if __name__ == "__main__":
    main(sys.argv[1:])
