#!/usr/bin/env python3
"""Regenerates the measured column of book/src/verification.md from the tests.

    python3 book/verification.py              (runs the tests, rewrites the chapter)
    python3 book/verification.py --records F  (rewrites it from a records file kept earlier)

The tests that check the chapter's rows call `record(row, quantity, value)` (src/verify_record.rs,
`common::verify` in the integration tests) with the figure each assertion bounds. With the
environment variable SOFTWAY_VERIFY_OUT naming a file, every call appends one line
`row<TAB>quantity<TAB>value`; unset (CI), nothing is written. This script runs the tests
concerned (`cargo test --all-features`, no ignored test) with it set, then fills the last
column of every table row that carries a key comment,

    | problem | what is compared | result | <!-- verify: KEY: quantity, quantity --> figures |

with `quantity value`, or `quantity min to max` when several tests or variants recorded it
(2D and 3D, each method, every step of a loop). It fails, naming the row, when a row of the
tables has no key comment, when a key or a listed quantity has no record, or when a test records
a quantity its row does not list. A row whose test cannot record says so explicitly with
`<!-- verify: KEY: none (reason) -->` and is listed on every run. Standard library only.
"""

import argparse
import datetime
import math
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import textwrap
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
CHAPTER = ROOT / "book" / "src" / "verification.md"

# (cargo test target arguments, test name filters): the tests the chapter's rows name.
RUNS = [
    (["--lib"], ["time::tests::", "friction::tests::", "assembly::tests::", "hypoelastic::tests::", "gap::tests::"]),
    # tests/suite.rs: every file of tests/ is a module of one binary; each filter names a file
    # (`foundation::`; `contact::` also selects self_contact.rs, a substring) or tests that only
    # one file has.
    (["--test", "suite"], [
        "foundation::", "contact::", "step_size_changes::", "locking::", "gripper::", "damping::",
        "rolling::", "friction::slide::", "friction::stick::", "undamped_floor_reaction",
        "bundled_scenes::cantilever", "bundled_scenes::gmsh_plate", "bundled_scenes::thick_cylinder",
        "a_stack_under_the_soft_way", "a_coulomb_stack_under", "a_tresca_stack_under", "a_spinning_body_comes_back_unstressed", "pendulum",
        "a_pre_stressed_spinning_ring",
        "threaded_factorisations_are_thread_independent", "_between_bodies",
    ]),
]

KEY = re.compile(r"<!-- verify: ([A-Za-z0-9-]+): (.*?) -->")
BEGIN, END = "<!-- verification.py: begin -->", "<!-- verification.py: end -->"


def commands():
    return [["cargo", "test", "--all-features", *target, *(["--", *filters] if filters else [])]
            for target, filters in RUNS]


def run_tests(out):
    env = dict(os.environ, SOFTWAY_VERIFY_OUT=str(out))
    for command in commands():
        print("+", " ".join(command), flush=True)
        done = subprocess.run(command, cwd=ROOT, env=env)
        if done.returncode != 0:
            sys.exit(f"verification.py: `{' '.join(command)}` failed ({done.returncode})")


def read_records(path):
    records = {}
    for number, line in enumerate(pathlib.Path(path).read_text().splitlines(), 1):
        parts = line.split("\t")
        if len(parts) != 3:
            sys.exit(f"verification.py: {path}:{number}: not row<TAB>quantity<TAB>value: {line!r}")
        row, quantity, value = parts
        records.setdefault(row, {}).setdefault(quantity, []).append(float(value))
    return records


def number(v):
    """Two significant digits: 0.031, -4.5e-3, 2.1e-12, 1.8e3; integers as they are."""
    if math.isnan(v) or math.isinf(v):
        return str(v)
    if v == int(v) and abs(v) < 1e6:
        return str(int(v))
    a = abs(v)
    if 1e-2 <= a < 1e3:
        digits = max(0, 1 - math.floor(math.log10(a)))
        return f"{v:.{digits}f}"
    mantissa, exponent = f"{v:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def figure(values):
    low, high = min(values), max(values)
    if number(low) == number(high):
        return number(low)
    return f"{number(low)} to {number(high)}"


def machine():
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        model = next(line.split(":", 1)[1].strip() for line in lscpu.splitlines()
                     if line.startswith("Model name"))
    except (OSError, StopIteration):
        model = "unknown processor"
    return f"{model}, {os.cpu_count()} cores"


def header(seconds):
    date = datetime.date.today().isoformat()
    prose = (
        f"The **measured** column is generated: `python3 book/verification.py` ran the tests below "
        f"on {date} ({machine()}; {seconds / 60:.0f} min, rebuilding the test binaries it needed) "
        "with `SOFTWAY_VERIFY_OUT` set, and wrote in each row the figure its assertions bound, "
        "recorded by the test just before the assertion: relative errors (fractions, signed "
        "where the test's is) unless a unit or a ratio is named, counts of mismatches where the "
        "test compares bits or sets; `min to max` over the variants the row covers (2D and 3D, "
        "methods, laws, elements, steps of a loop). Ignored tests are not run. Edit the other "
        "columns by hand; rerun the command for this one."
    )
    lines = [
        BEGIN,
        *textwrap.wrap(prose, 100, break_on_hyphens=False),
        "",
        "```text",
        *(" ".join(c) for c in commands()),
        "```",
        END,
    ]
    return "\n".join(lines)


def rewrite(text, records, seconds):
    problems, unrecorded, used = [], [], set()
    out = []
    for number_, line in enumerate(text.splitlines(), 1):
        if not line.startswith("|") or line.startswith(("| problem ", "| ---")):
            out.append(line)
            continue
        m = KEY.search(line)
        if not m:
            problems.append(f"line {number_}: a table row without `<!-- verify: KEY: ... -->`: {line[:80]}")
            out.append(line)
            continue
        key, spec = m.group(1), m.group(2)
        if spec.startswith("none"):
            unrecorded.append(f"{key}: {spec}")
            out.append(f"{line[:m.start()]}{m.group(0)} not recorded{spec[len('none'):]} |")
            continue
        got = records.get(key)
        if got is None:
            problems.append(f"line {number_}: row `{key}` has no record ({line[:70]} ...)")
            out.append(line)
            continue
        used.add(key)
        quantities = [q.strip() for q in spec.split(",")]
        missing = [q for q in quantities if q not in got]
        extra = [q for q in got if q not in quantities]
        if missing:
            problems.append(f"line {number_}: row `{key}`: no record of {missing}")
        if extra:
            problems.append(f"line {number_}: row `{key}`: recorded {extra}, not listed in its comment")
        cell = "; ".join(f"{q} {figure(got[q])}" for q in quantities if q in got)
        out.append(f"{line[:m.start()]}{m.group(0)} {cell} |")
    for key in sorted(set(records) - used):
        problems.append(f"records of `{key}`, which no row names")
    if problems:
        sys.exit("verification.py:\n  " + "\n  ".join(problems))
    text = "\n".join(out) + "\n"
    begin, end = text.index(BEGIN), text.index(END) + len(END)
    return text[:begin] + header(seconds) + text[end:], unrecorded


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--records", help="a records file kept from an earlier run (no tests run)")
    parser.add_argument("--keep", help="copy the records to this file")
    args = parser.parse_args()
    start = time.monotonic()
    if args.records:
        records_path = pathlib.Path(args.records)
    else:
        records_path = pathlib.Path(tempfile.mkdtemp()) / "verification.tsv"
        records_path.touch()
        run_tests(records_path)
        if args.keep:
            pathlib.Path(args.keep).write_text(records_path.read_text())
    seconds = time.monotonic() - start
    records = read_records(records_path)
    old = CHAPTER.read_text()
    if args.records:
        # Keep the header's time from the run that produced the records.
        m = re.search(r"; (\d+) min, rebuilding", old)
        seconds = 60 * int(m.group(1)) if m else seconds
    new, unrecorded = rewrite(old, records, seconds)
    CHAPTER.write_text(new)
    n = sum(len(v) for q in records.values() for v in q.values())
    print(f"verification.py: {n} records, {len(records)} rows; wrote {CHAPTER.relative_to(ROOT)}")
    for row in unrecorded:
        print(f"verification.py: not recorded: {row}")


if __name__ == "__main__":
    main()
