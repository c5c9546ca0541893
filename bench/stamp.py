#!/usr/bin/env python3
"""The stamp of a generated table (issue 33): the one place that says what a measurement ran on.

Every table file under docs/src/results/tables/ starts with one line,

    Command: `COMMAND`; commit abc1234[-dirty]; `rsasim 0.8.0 (abc1234)`; AMD EPYC, 2 logical
    CPUs, 23.5 GiB RAM; 2026-11-27 14:40 UTC[; load average …]

then a blank line and the table. The commit is the work tree's HEAD, `-dirty` when a file outside docs/ and
CHANGELOG.md differs from it or is untracked (prose and the tables a generator writes change no
measurement); the version line is the binary's own, which names
the commit it was built from. Timing tables add the load average (1, 5 and 15 min) at the start
and at the end of the measurement, so a reader sees how busy the machine was.

From Python (the generators under bench/ import it):

    import stamp
    start = stamp.load()                       # timing tables only, before measuring
    stamp.write(path, "bench/x.py …", table_text, binary=…, load_start=start)

From a shell script:

    bench/stamp.py line --command "bench/x.sh …" [--bin PATH] [--load-start "0.5 0.4 0.3"]
    bench/stamp.py load                        # prints the load average now
    bench/stamp.py write FILE --command "…" [--bin PATH] [--load-start …] < table.md

Standard library only.
"""

import argparse
import datetime
import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
TABLES = "docs/src/results/tables"


def git(*args):
    done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return done.stdout.strip() if done.returncode == 0 else ""


def commit():
    """HEAD's short hash, with `-dirty` when the tree differs from it (the manual and the
    changelog aside: they change no measurement, and the tables are written into them; so do the
    `.bench-*` scenarios a bench writes beside the shipped ones while it runs)."""
    head = git("rev-parse", "--short", "HEAD") or "unknown"
    status = git("status", "--porcelain", "--", ".", ":(exclude)docs", ":(exclude)CHANGELOG.md",
                 ":(exclude,glob)**/.bench-*")
    return head + ("-dirty" if status else "")


def target_dir():
    """Cargo's target folder (CARGO_TARGET_DIR or the workspace's)."""
    done = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"], cwd=ROOT,
                          capture_output=True, text=True)
    if done.returncode == 0:
        return pathlib.Path(json.loads(done.stdout)["target_directory"])
    return pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))


def release_binary(build=True):
    """$RSASIM_BIN when set (not rebuilt: its version line says what it was built from), else
    the release `rsasim`, built first (`cargo build --release --locked --bin rsasim`)."""
    if os.environ.get("RSASIM_BIN"):
        return pathlib.Path(os.environ["RSASIM_BIN"]).resolve()
    if build:
        subprocess.run(["cargo", "build", "--release", "--locked", "--quiet", "--bin", "rsasim"],
                       cwd=ROOT, check=True)
    return target_dir() / "release" / "rsasim"


def version(binary):
    """The binary's `--version` line."""
    if binary is None:
        return None
    done = subprocess.run([str(binary), "--version"], capture_output=True, text=True)
    return (done.stdout.strip().splitlines() or ["unknown version"])[0]


def machine():
    """CPU model, logical CPUs and RAM, from /proc."""
    cpu = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    ram = ""
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal:"):
                ram = f", {int(line.split()[1]) / 1048576:.1f} GiB RAM"
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical CPUs{ram}"


def load():
    """The load average now: '1-min 5-min 15-min'."""
    try:
        return " ".join(open("/proc/loadavg").read().split()[:3])
    except OSError:
        return "unknown"


def now():
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def line(command, binary=None, load_start=None, note=None, version_line=None, commit_text=None):
    """The first line of a table file. `binary`'s --version is cited (or `version_line`, for a
    binary that is gone); `load_start` (a timing table's load before measuring) adds the load
    average then and now; `note` is appended as it is. `commit_text` replaces this work tree's
    commit, for a measurement of another checkout (a fresh clone of a commit)."""
    parts = [f"Command: `{command}`", f"commit {commit_text or commit()}"]
    v = version_line or version(binary)
    if v:
        parts.append(f"`{v}`")
    parts += [machine(), now()]
    if load_start is not None:
        parts.append(f"load average {load_start} at the start, {load()} at the end (1, 5, 15 min)")
    text = "; ".join(parts)
    if note:
        text += f". {note}"
    return text


def output_origin(out, results_name):
    """What an analysed output folder is, from its manifest.json and its first run's results
    file `results_name`: the scenario, its seed, the build that wrote the output and the software
    that wrote the results (for tables computed from an output rather than a binary's run)."""
    out = pathlib.Path(out)
    try:
        m = json.loads((out / "manifest.json").read_text())
    except (OSError, ValueError):
        return "an output without a readable manifest.json"
    build = m.get("build", {})
    text = (f"scenario `{m.get('scenario')}` (seed {m.get('seed')}) written by `{m.get('program')}` "
            f"at {str(build.get('commit', 'unknown'))[:7]}")
    for run in sorted((out / "runs").iterdir()) if (out / "runs").is_dir() else []:
        try:
            software = json.loads((run / results_name).read_text()).get("software")
        except (OSError, ValueError):
            continue
        return f"{text}, results `{results_name}` by `{software}`"
    return text


def write(path, command, table, binary=None, load_start=None, note=None, version_line=None, commit_text=None):
    """Writes a table file: the stamp line, a blank line, the table (Markdown)."""
    path = pathlib.Path(path)
    if not path.is_absolute():
        path = ROOT / path
    path.write_text(line(command, binary, load_start, note, version_line, commit_text) + "\n\n"
                    + table.strip("\n") + "\n")
    print(f"wrote {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("line", "write"):
        p = sub.add_parser(name)
        if name == "write":
            p.add_argument("file")
        p.add_argument("--command", required=True)
        p.add_argument("--bin", default=None, help="the rsasim binary whose --version to cite")
        p.add_argument("--load-start", default=None)
        p.add_argument("--note", default=None)
    sub.add_parser("load")
    args = ap.parse_args()
    if args.cmd == "load":
        print(load())
    elif args.cmd == "line":
        print(line(args.command, args.bin, args.load_start, args.note))
    else:
        write(args.file, args.command, sys.stdin.read(), args.bin, args.load_start, args.note)


if __name__ == "__main__":
    main()
