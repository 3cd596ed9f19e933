#!/usr/bin/env python3
"""Times ipctk's swept candidate search on the surfaces softway's detection bench exports.

    pip install ipctk numpy
    SOFTWAY_EXPORT_DIR=target/detection-meshes cargo bench --bench detection
    python3 benches/compare/ipctk_candidates.py target/detection-meshes [softway_ms_10k,100k,1M]

For each sphere_<n>_x0.obj / sphere_<n>_x1.obj pair (same triangles, every vertex moved by up
to 0.17 mean edge lengths) it times, inflation radius 0, medians of several runs:
  * LBVH face-vertex: ipctk.LBVH().build(V0, V1, E, F) + detect_face_vertex_candidates(), the
    work that matches softway's node-facet candidates;
  * LBVH all: Candidates().build(mesh, V0, V1, 0, LBVH()) (vertex-face + edge-edge + ...);
  * HashGrid all (ipctk's default broad phase), for the smaller surfaces.
It also counts ipctk's face-vertex candidates that softway's self-contact exclusion (facets
around the vertex and their neighbours) keeps: softway must report exactly those.
With softway's medians on the command line (milliseconds, same order as the files) it prints
the ratios.
"""
import glob
import os
import re
import statistics
import sys
import time

import numpy as np
import ipctk


def load_obj(path):
    v, f = [], []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                v.append(line.split()[1:4])
            elif line.startswith("f "):
                f.append(line.split()[1:4])
    return np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int32) - 1


def outside_exclusion(faces, n_vertices, fv_list):
    """ipctk's face-vertex candidates that softway's self-contact rule keeps: the face holds
    no vertex of a face around the vertex. softway reports exactly these (with margin 0)."""
    ring = [set() for _ in range(n_vertices)]
    for a, b, c in faces.tolist():
        for v in (a, b, c):
            ring[v].update((a, b, c))
    count = 0
    for cand in fv_list:
        if not ring[cand.vertex_id].intersection(faces[cand.face_id].tolist()):
            count += 1
    return count


def median_time(fn, repeats):
    times = []
    result = None
    for _ in range(repeats):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), result


def main():
    directory = sys.argv[1] if len(sys.argv) > 1 else "target/detection-meshes"
    ours = [float(s) for s in sys.argv[2].split(",")] if len(sys.argv) > 2 else []
    files = sorted(
        glob.glob(os.path.join(directory, "sphere_*_x0.obj")),
        key=lambda p: int(re.search(r"sphere_(\d+)_x0", p).group(1)),
    )
    if not files:
        sys.exit(f"no sphere_*_x0.obj in {directory}: run the bench with SOFTWAY_EXPORT_DIR")
    print(f"ipctk {ipctk.__version__}, numpy {np.__version__}")
    for i, f0 in enumerate(files):
        v0, faces = load_obj(f0)
        v1, faces1 = load_obj(f0.replace("_x0.obj", "_x1.obj"))
        assert (faces == faces1).all()
        edges = ipctk.edges(faces)
        repeats = 3 if len(faces) > 500_000 else 7

        def fv():
            bp = ipctk.LBVH()
            bp.build(v0, v1, edges, faces, 0.0)
            return bp.detect_face_vertex_candidates()

        t_fv, fv_list = median_time(fv, repeats)
        n_fv = len(fv_list)
        outside = outside_exclusion(faces, len(v0), fv_list)
        mesh = ipctk.CollisionMesh(v0, edges, faces)

        def all_candidates(bp):
            def run():
                c = ipctk.Candidates()
                c.build(mesh, v0, v1, 0.0, bp())
                return len(c.fv_candidates), len(c.ee_candidates)
            return run

        t_all, (n_fv_all, n_ee) = median_time(all_candidates(ipctk.LBVH), repeats)
        line = (
            f"{len(faces):>8} faces {len(v0):>7} vertices | LBVH face-vertex {t_fv * 1e3:8.1f} ms "
            f"({n_fv} candidates, {outside} outside softway's exclusion) | LBVH all {t_all * 1e3:8.1f} ms (fv {n_fv_all}, ee {n_ee})"
        )
        if len(faces) <= 200_000:
            t_grid, _ = median_time(all_candidates(ipctk.HashGrid), repeats)
            line += f" | HashGrid all {t_grid * 1e3:8.1f} ms"
        if i < len(ours):
            line += (
                f" | softway {ours[i]:.1f} ms: x{t_fv * 1e3 / ours[i]:.1f} vs LBVH fv, "
                f"x{t_all * 1e3 / ours[i]:.1f} vs LBVH all"
            )
        print(line, flush=True)


if __name__ == "__main__":
    main()
