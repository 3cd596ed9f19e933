#!/usr/bin/env python3
"""Screenshots of softway recordings in the native Rerun viewer, for the book.

    python3 book/rerun_screenshot.py RECORDING.rrd OUT.png [--bounds XMIN XMAX YMIN YMAX]

It writes a blueprint with softway's layout (the recorder's own, `src/recording/rerun/
blueprint.rs`) whose 2D view is framed on `--bounds` (m, the scene's axes; a half-space
obstacle is drawn as a long line, and the viewer's automatic framing would include all of it),
opens the recording with it under Xvfb with software Vulkan (`mesa-vulkan-drivers`: the GL
driver lacks R32Float targets) and lets the viewer write its own screenshot (`--screenshot-to`).
Needs `xvfb` and `mesa-vulkan-drivers` (Debian) and `rerun-sdk==0.36.3` (PyPI).
"""

import argparse
import os
import subprocess
import tempfile
import time

import rerun.blueprint as rrb


def blueprint(bounds):
    # 2D recordings are logged with y negated (the viewer draws y downwards).
    view_args = {}
    if bounds:
        xmin, xmax, ymin, ymax = bounds
        view_args["visual_bounds"] = rrb.VisualBounds2D(x_range=[xmin, xmax], y_range=[-ymax, -ymin])
    scene = rrb.Spatial2DView(
        name="Bodies and contacts",
        contents=["bodies/**", "obstacles/**", "contacts/**"],
        **view_args,
    )
    residuals = rrb.Tabs(
        rrb.TimeSeriesView(name="Residual norm [N]", contents=["solver/residual_norm"]),
        rrb.TimeSeriesView(name="Relative residual", contents=["solver/relative_residual"]),
        rrb.TimeSeriesView(name="Increment norm [m/s]", contents=["solver/increment_norm"]),
    )
    plots = rrb.Vertical(
        residuals,
        rrb.TimeSeriesView(name="Active set", contents=["solver/active_set_size", "solver/candidates"]),
        rrb.TimeSeriesView(name="Energy [J]", origin="energy"),
        rrb.TextLogView(name="Log", origin="log"),
    )
    return rrb.Blueprint(
        rrb.Horizontal(scene, plots, column_shares=[2.0, 1.0]),
        rrb.TimePanel(timeline="iteration", play_state="following"),
        rrb.SelectionPanel(state="collapsed"),
    )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("recording")
    parser.add_argument("out")
    parser.add_argument("--bounds", type=float, nargs=4, metavar=("XMIN", "XMAX", "YMIN", "YMAX"))
    parser.add_argument(
        "--last-part", type=int, metavar="N",
        help="show only the last N-th of the iterations (`rerun rrd split`): the viewer takes "
        "its screenshot after its first frames, before a large recording has loaded",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        # Split even when the whole run is shown: the parts hold no blueprint, so the viewer
        # takes this one.
        parts = ["-n", str(args.last_part)] if args.last_part else ["-t", "1000000000"]
        subprocess.run(
            ["rerun", "rrd", "split", "--output-dir", tmp, "--timeline", "iteration",
             *parts, args.recording],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        # Named <stem>_<from>__<to>.rrd: with -n the last part starts latest; with -t the
        # whole run is the part [-inf, 1e9), the largest.
        splits = [f for f in os.listdir(tmp) if f.endswith(".rrd")]
        if args.last_part:
            last = max(splits, key=lambda f: int(f.rsplit("__", 1)[0].rsplit("_", 1)[1]))
        else:
            last = max(splits, key=lambda f: os.path.getsize(os.path.join(tmp, f)))
        recording = os.path.join(tmp, last)
        rbl = os.path.join(tmp, "layout.rbl")
        blueprint(args.bounds).save("softway", rbl)
        # One file, blueprint first: two sources race, and the screenshot may come first.
        merged = os.path.join(tmp, "merged.rrd")
        with open(merged, "wb") as out:
            subprocess.run(["rerun", "rrd", "merge", rbl, recording], check=True, stdout=out,
                           stderr=subprocess.DEVNULL)
        display = ":97"
        xvfb = subprocess.Popen(["Xvfb", display, "-screen", "0", "1600x1000x24"])
        env = dict(os.environ, DISPLAY=display, WGPU_BACKEND="vulkan")
        try:
            time.sleep(2)
            subprocess.run(
                ["rerun", merged, "--bind", "127.0.0.1", "--port", "auto",
                 "--window-size", "1400x850", "--screenshot-to", args.out],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )
        finally:
            xvfb.terminate()
            xvfb.wait()
        if not os.path.exists(args.out):
            raise SystemExit(f"no screenshot written to {args.out}")


if __name__ == "__main__":
    main()
