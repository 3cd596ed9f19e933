#!/usr/bin/env python3
"""The soft cube of the peer figures, MuJoCo's flex beside softway, from one script.

A 0.2 m cube (E = 1e5 Pa, nu = 0.3, 8 kg: 1000 kg/m^3) of 8 x 8 x 8 nodes (7^3 cubes, 2058
tetrahedra on both sides) dropped from rest 0.1 m onto a rigid plane, gravity 9.81 m/s^2, 2
simulated seconds:

* MuJoCo (the Python package `mujoco`): `flexcomp type="grid" dim="3"`, elasticity
  young = 1e5, poisson = 0.3, damping 0, on a plane; its Euler integrator at 1e-3 s (its
  stability limit is about 1.4e-3 s) and its `discrete` integrator (implicit in the flex elasticity) at 1e-2 s;
* softway (`softway run` on a scene this script writes, the `box` generator with tet4) at
  1e-2 s: implicit projection (the default method), undamped and with a material damping of
  5 % of critical at the cube's first mode (MuJoCo's runs come to rest through their contact
  and integrator damping; softway's elastic cube otherwise keeps ringing), and the soft way
  (zeta = 1e8 Pa/m), damped, on the paper's configuration gaps and on trapezoid gaps.

Printed per run: wall time per simulated second (MuJoCo timed around `mj_step`; softway's
`wall_seconds` from its summary, which includes writing the history), the deepest a node went
below the plane, the sag at the end (the top probe's downward displacement less the bottom
probe's, against the frictionless column's rho g H^2 / (2 E) = 1.96 mm) and the kinetic energy
left.

Run: `python3 benches/compare/mujoco_flex.py [SOFTWAY_BINARY]` from the repository (default
`target/release/softway`; build it with `cargo build --release`). Needs `pip install mujoco`
(4.0.0 measured).
"""

import csv
import json
import os
import subprocess
import sys
import tempfile
import time

import mujoco
import numpy as np

SIZE, DROP, YOUNG, POISSON, DENSITY, G, END = 0.2, 0.1, 1e5, 0.3, 1000.0, 9.81, 2.0
COUNT = 8  # nodes per edge
MASS = DENSITY * SIZE**3


def mujoco_run(integrator, dt):
    spacing = SIZE / (COUNT - 1)
    xml = f"""
<mujoco>
  <option timestep="{dt}" integrator="{integrator}" gravity="0 0 {-G}"/>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <flexcomp name="cube" type="grid" dim="3" count="{COUNT} {COUNT} {COUNT}"
              spacing="{spacing} {spacing} {spacing}" pos="0 0 {DROP + SIZE / 2}"
              mass="{MASS}" radius="0.0005">
      <edge equality="false"/>
      <elasticity young="{YOUNG}" poisson="{POISSON}" damping="0"/>
    </flexcomp>
  </worldbody>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    x0 = data.flexvert_xpos.copy()
    top = x0[:, 2] > x0[:, 2].max() - 1e-9
    bottom = x0[:, 2] < x0[:, 2].min() + 1e-9
    steps = int(round(END / dt))
    deepest, wall, failed = 0.0, 0.0, None
    for k in range(steps):
        t = time.perf_counter()
        mujoco.mj_step(model, data)
        wall += time.perf_counter() - t
        z = data.flexvert_xpos[:, 2]
        if not np.all(np.isfinite(z)) or data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            failed = f"unstable at step {k + 1}"
            break
        deepest = max(deepest, -z.min())
    x = data.flexvert_xpos
    sag = (x0[top, 2].mean() - x[top, 2].mean()) - (x0[bottom, 2].mean() - x[bottom, 2].mean())
    kinetic = 0.5 * float(np.dot(data.qvel, data.qvel)) * MASS / (COUNT**3)
    return (f"MuJoCo {integrator}, dt {dt:g}", failed, wall / END, deepest, sag, kinetic)


SCENE = """[simulation]
dimension = 3
time_step = {dt}
end_time = {end}
gravity = [0.0, 0.0, -9.81]

[contact]
method = "{method}"
{penalty}

[[bodies]]
name = "cube"
mesh = {{ generator = "box", min = [0.0, 0.0, {drop}], max = [{size}, {size}, {top}], cells = [{n}, {n}, {n}], element = "tet4" }}
material = {{ model = "linear_elastic", youngs_modulus = {young}, poissons_ratio = {poisson}, density = {density} }}
damping = {{ mass = 0.0, stiffness = {damping} }}

[[obstacles]]
name = "floor"
shape = {{ type = "halfspace", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}

[[probes]]
name = "top"
body = "cube"
point = [{half}, {half}, {top}]

[[probes]]
name = "bottom"
body = "cube"
point = [{half}, {half}, {drop}]

[output]
vtk_interval = 0.0
"""


def softway_run(binary, method, dt, damped, trapezoid=False):
    penalty = "penalty = 1.0e8" if method == "soft_way" else ""
    if trapezoid:
        penalty += '\ngap_displacement = "trapezoid"'
    # 5 % of critical at the first axial mode, omega = pi c / (2 H), stiffness-proportional.
    omega = np.pi * np.sqrt(YOUNG / DENSITY) / (2 * SIZE)
    damping = 2 * 0.05 / omega if damped else 0.0
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "cube.toml")
        with open(scene, "w") as f:
            f.write(SCENE.format(dt=dt, end=END, method=method, penalty=penalty, drop=DROP,
                                 size=SIZE, top=DROP + SIZE, half=SIZE / 2, n=COUNT - 1,
                                 young=YOUNG, poisson=POISSON, density=DENSITY,
                                 damping=damping))
        out = os.path.join(tmp, "out")
        run = subprocess.run([binary, "run", scene, "--out", out, "--quiet"],
                             capture_output=True, text=True)
        failed = None if run.returncode == 0 else run.stderr.strip().splitlines()[-1]
        summary = json.load(open(os.path.join(out, "summary.json")))
        rows = list(csv.DictReader(open(os.path.join(out, "history.csv"))))
    last = rows[-1]
    sag = float(last["probe.bottom.uz"]) - float(last["probe.top.uz"])
    label = f"softway {method}{', trapezoid' if trapezoid else ''}{', damped' if damped else ''}"
    return (f"{label}, dt {dt:g}", failed, summary["wall_seconds"] / END,
            summary["max_penetration"], sag, float(last["kinetic_energy"]))


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else "target/release/softway"
    print(f"soft cube: {COUNT}^3 nodes, {6 * (COUNT - 1)**3} tetrahedra, {END} s simulated; "
          f"reference sag rho g H^2 / (2 E) = {1e3 * DENSITY * G * SIZE**2 / (2 * YOUNG):.2f} mm; "
          f"mujoco {mujoco.__version__}")
    runs = [
        mujoco_run("Euler", 1e-3),
        mujoco_run("discrete", 1e-2),
        softway_run(binary, "implicit_projection", 1e-2, False),
        softway_run(binary, "implicit_projection", 1e-2, True),
        softway_run(binary, "soft_way", 1e-2, True),
        softway_run(binary, "soft_way", 1e-2, True, trapezoid=True),
    ]
    base = runs[0][2]
    for label, failed, wall, deepest, sag, kinetic in runs:
        state = f"; {failed}" if failed else ""
        print(f"  {label:<50} {wall:.3f} s/s ({wall / base:.2f}x MuJoCo Euler); deepest "
              f"{1e3 * deepest:.2f} mm; sag {1e3 * sag:.2f} mm; kinetic energy left "
              f"{kinetic:.2e} J{state}")


if __name__ == "__main__":
    main()
