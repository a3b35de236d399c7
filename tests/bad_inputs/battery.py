"""A battery of bad or unusual inputs to crackle (issue 71), run and classified.

Not a pytest module (no test_ prefix): run it by hand,

    python tests/bad_inputs/battery.py [--only ID,...] [--items 1,3] [--jobs N]
        [--out REPORT.md] [--src PATH] [--work DIR] [--timeout S]   (default: TMPDIR/crackle-battery/)

Each input of inputs.toml (beside this file) runs `python -m crackle.cli ARGS` in its own folder
WORK/ID (cwd), with PYTHONPATH set to --src (default: this repository's src). Placeholders in
args, env, shell and file contents: {dir} the input's folder, {out} {dir}/out, {src} the src
folder, {examples} the shipped examples' folder, {crackle} (shell only) the command prefix.

An input's fields:
  id, item (1-10 of issue 71), expect: "refuse" (exit 2, a message naming `msg`), "run" (exit 0),
  "stop" (exit 130, 1 or 3 with outputs kept), "either" (0 or 2, no traceback);
  args: list; env: table; shell: a bash line instead of args (pipes, ulimit);
  files: [{path, kind, ...}] made first (kinds: text, spheres, npz_foreign, junk, tet_mesh,
  copy_example); sentinels: [paths] user files made first, which must survive unchanged;
  pre: [{args, signal, after}] commands run first (a previous run, its outputs kept);
  mutate: "tear_history" (cut the last row of {out}/history.csv in half before the main command);
  signals: [{name, after}] sent to the main command's process group (after s from its start);
  checks: ["summary", "checkpoint", "status_final", "no_lock", "keep_outputs", "examples_whole",
  "prompt_exit", "history_monotonic", "msg_short"]; warn: regex that on exit 0 counts as a
  warning given (refuse-or-warn inputs); msg: regex the message should match; timeout: s.

Classes: traceback ("Traceback" in the output), lost data (a sentinel changed or gone, earlier
outputs gone, a stopped run without summary/checkpoint), silent (expected refuse, exit 0 with no
warning), timeout, killed (ended by a signal: no handler), clean (exit as expected, message
matches), unclear (anything else: a person reads the message).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import csv
import hashlib
import json
import os
import re
import shlex
import shutil
import signal as sigmod
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent


def fill(text, ctx):
    if not isinstance(text, str):
        return text
    for k, v in ctx.items():
        text = text.replace("{" + k + "}", str(v))
    return text


# ---------------------------------------------------------------- files
def make_spheres(path, spec):
    import numpy as np

    rng = np.random.default_rng(spec.get("seed", 0))
    lo = np.array(spec.get("origin", [0.0, 0.0, 0.0]), float)
    ext = np.array(spec.get("extent", [0.027, 0.012, 0.054]), float)
    r = float(spec.get("radius", 1e-3))
    step = 2 * r * float(spec.get("spacing_factor", 0.98))
    axes = [np.arange(lo[i] + r, lo[i] + ext[i] - r + 1e-12, step) for i in range(3)]
    g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    g = g + rng.uniform(-0.02 * r, 0.02 * r, g.shape)
    radii = r * rng.uniform(0.9, 1.0, len(g))
    n = spec.get("count")
    if n:
        g, radii = g[:n], radii[:n]
    rows = [list(p) + [q] for p, q in zip(g, radii)]
    dup = spec.get("duplicate", 0)  # "all": a doubled export; N: N clumps (same centre)
    if dup == "all":
        rows = rows + [list(x) for x in rows]
    elif dup:
        for i in range(int(dup)):
            x = list(rows[i * 7])
            x[3] = x[3] * 0.5
            rows.append(x)
    unit = float(spec.get("unit", 1.0))  # 1000: written in mm
    sep = spec.get("sep", " ")
    lines = [spec["header"]] if spec.get("header") else []
    for x in rows:
        vals = [f"{v * unit:.9g}" for v in x[:4]]
        if spec.get("columns"):
            vals = vals[: spec["columns"]]
        if spec.get("group"):
            vals.append(str(spec["group"]))
        lines.append(sep.join(vals))
    for bad in spec.get("append", []):
        lines.append(bad)
    Path(path).write_text("\n".join(lines) + "\n")


def make_tet_mesh(path, spec):
    import meshio
    import numpy as np

    n = int(spec.get("n", 4))
    size = np.array(spec.get("size", [0.02, 0.02, 0.02]), float)
    center = np.array(spec.get("center", [0.0, 0.0, 0.0]), float)
    scale = float(spec.get("unit", 1.0))
    xs = [np.linspace(-s / 2, s / 2, n + 1) for s in size]
    pts = np.stack(np.meshgrid(*xs, indexing="ij"), -1).reshape(-1, 3) + center
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    tets = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                c = [idx[i + a, j + b, k + d] for a in (0, 1) for b in (0, 1) for d in (0, 1)]
                # a cube into 6 tets along the 0-7 diagonal
                v0, v1, v2, v3, v4, v5, v6, v7 = c
                tets += [[v0, v1, v3, v7], [v0, v1, v5, v7], [v0, v4, v5, v7],
                         [v0, v2, v3, v7], [v0, v2, v6, v7], [v0, v4, v6, v7]]
    tets = np.array(tets)
    p = pts[tets]
    vol = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    meshio.write(str(path), meshio.Mesh(pts * scale, [("tetra", tets)]))


def make_file(d, f, ctx):
    path = d / fill(f["path"], ctx)
    path.parent.mkdir(parents=True, exist_ok=True)
    kind = f.get("kind", "text")
    if kind == "text":
        path.write_text(fill(f.get("content", ""), ctx))
    elif kind == "spheres":
        make_spheres(path, f)
    elif kind == "npz_foreign":
        import numpy as np

        np.savez(path, positions=np.zeros((10, 3)), radius=np.ones(10), meta=np.array(["lammps"]))
    elif kind == "junk":
        path.write_bytes(bytes((i * 97 + 13) % 256 for i in range(int(f.get("size", 4096)))))
    elif kind == "tet_mesh":
        make_tet_mesh(path, f)
    elif kind == "copy_example":
        src = Path(ctx["examples"]) / (f["example"] + ".toml")
        text = src.read_text()
        for a, b in f.get("replace", []):
            if a not in text:
                raise SystemExit(f"{f['example']}: {a!r} not in the example")
            text = text.replace(a, fill(b, ctx), 1)
        path.write_text(text + fill(f.get("append", ""), ctx))
    elif kind == "dir":
        path.mkdir(parents=True, exist_ok=True)
    else:
        raise SystemExit(f"unknown file kind {kind}")
    if f.get("mode"):
        os.chmod(path, int(f["mode"], 8))


def digest(path):
    p = Path(path)
    if not p.exists():
        return None
    if p.is_dir():
        return "dir"
    return hashlib.sha256(p.read_bytes()).hexdigest()


def tree(d):
    out = {}
    if Path(d).is_dir():
        for p in sorted(Path(d).rglob("*")):
            if p.is_file():
                out[str(p.relative_to(d))] = p.stat().st_size
    return out


def history_rows(out):
    p = Path(out) / "history.csv"
    if not p.exists():
        return None
    return max(0, len(p.read_text(errors="replace").splitlines()) - 1)


# ---------------------------------------------------------------- running
def _default_signals():
    for name in ("SIGINT", "SIGQUIT"):
        sigmod.signal(getattr(sigmod, name), sigmod.SIG_DFL)


def run_proc(cmd, shell, env, cwd, timeout, signals):
    """Run one command in its own process group; send signals; return (rc, out, err, wall, t_sig)."""
    t0 = time.time()
    # SIGINT and SIGQUIT back to their defaults: a battery started in the background of a script
    # has them ignored, and a command would inherit that (a sweep then cannot be stopped by Ctrl-C).
    p = subprocess.Popen(cmd if not shell else ["bash", "-c", cmd], cwd=cwd, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                         start_new_session=True, preexec_fn=_default_signals)
    import threading

    last_sig = [None]

    def sender():
        for s in signals:
            delay = t0 + float(s["after"]) - time.time()
            if delay > 0:
                time.sleep(delay)
            if p.poll() is not None:
                return
            try:
                os.killpg(p.pid, getattr(sigmod, s["name"]))
                last_sig[0] = time.time()
            except ProcessLookupError:
                return

    th = threading.Thread(target=sender, daemon=True)
    th.start()
    timed_out = False
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        try:
            os.killpg(p.pid, sigmod.SIGINT)
            out, err = p.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, sigmod.SIGKILL)
            out, err = p.communicate()
    wall = time.time() - t0
    after_sig = (time.time() - last_sig[0]) if last_sig[0] else None
    return (None if timed_out else p.returncode, out.decode(errors="replace"),
            err.decode(errors="replace"), wall, after_sig)


def first_message(out, err):
    for text in (err, out):
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
        lines = [ln for ln in lines if not ln.startswith("__RC__")]
        if not lines:
            continue
        for ln in lines:  # the first line that looks like an error or warning
            if re.search(r"error|refus|cannot|must|invalid|not |warning|unknown|missing", ln, re.I):
                return ln
        return lines[-1]
    return ""


def run_input(inp, args, examples):
    iid = inp["id"]
    d = Path(args.work) / iid
    if d.exists():
        for p in [d, *d.rglob("*")]:  # read-only folders of an earlier run
            try:
                os.chmod(p, 0o755 if p.is_dir() else 0o644)
            except OSError:
                pass
        shutil.rmtree(d)
    d.mkdir(parents=True)
    ctx = {"dir": d, "out": d / "out", "src": args.src, "examples": examples, "pid": os.getpid(),
           "host": socket.gethostname()}
    base_env = dict(os.environ)
    base_env["PYTHONPATH"] = args.src + os.pathsep + base_env.get("PYTHONPATH", "")
    base_env.pop("CRACKLE_LOG_INTERVAL", None)
    notes = []
    for f in inp.get("files", []):
        make_file(d, f, ctx)
    sentinels = {}
    for s in inp.get("sentinels", []):
        p = d / fill(s, ctx)
        p.parent.mkdir(parents=True, exist_ok=True)
        if p.name == "history.csv":
            p.write_text("time,my_own_measurement\n0.0,1.0\n0.1,2.0\n")
        else:
            p.write_text(f"user's own file {p.name}, do not remove\n")
        sentinels[str(p)] = digest(p)
    crackle = [sys.executable, "-m", "crackle.cli"]
    for pre in inp.get("pre", []):
        env = dict(base_env)
        env.update({k: fill(v, ctx) for k, v in pre.get("env", {}).items()})
        sig = [{"name": pre["signal"], "after": pre["after"]}] if pre.get("signal") else []
        rc, o, e, w, _ = run_proc(crackle + [fill(a, ctx) for a in pre["args"]], False, env, d,
                                  args.timeout, sig)
        notes.append(f"pre exit {rc} ({w:.0f} s)")
        if "Traceback" in o + e:
            notes.append("pre: traceback")
    if inp.get("mutate") == "tear_history":
        h = ctx["out"] / "history.csv"
        if h.exists():
            text = h.read_text()
            lines = text.splitlines()
            if len(lines) > 2:
                h.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][: len(lines[-1]) // 2])
                notes.append(f"tore row {len(lines) - 1} of {len(lines) - 1}")
    before_tree = tree(ctx["out"])
    before_rows = history_rows(ctx["out"])
    before_digests = {k: digest(ctx["out"] / k) for k in before_tree}
    env = dict(base_env)
    env.update({k: fill(v, ctx) for k, v in inp.get("env", {}).items()})
    if "shell" in inp:
        cmd_text = fill(inp["shell"], dict(ctx, crackle=" ".join(map(shlex.quote, crackle))))
        cmd = cmd_text + '; echo "__RC__${PIPESTATUS[0]}" >&2'
        shell = True
    else:
        cmd = crackle + [fill(a, ctx) for a in inp["args"]]
        cmd_text = "crackle " + " ".join(shlex.quote(a) for a in cmd[3:])
        shell = False
    prefix = " ".join(f"{k}={shlex.quote(str(v))}" for k, v in inp.get("env", {}).items())
    if prefix:
        cmd_text = prefix + " " + cmd_text
    timeout = inp.get("timeout", args.timeout)
    rc, out, err, wall, after_sig = run_proc(cmd, shell, env, d, timeout, inp.get("signals", []))
    if shell and rc is not None:
        m = re.findall(r"__RC__(\d+)", err)
        if m:
            rc = int(m[-1])
    text = out + err
    expect = inp["expect"]
    cls, why = None, []
    # lost data
    for p, h in sentinels.items():
        now = digest(p)
        if now != h:
            why.append(f"user file {Path(p).relative_to(d)} {'gone' if now is None else 'changed'}")
    checks = inp.get("checks", [])
    outdir = ctx["out"]
    if expect == "refuse" and before_tree:
        after = {k: digest(outdir / k) for k in before_tree}
        changed = [k for k in before_tree if after[k] != before_digests[k]]
        if changed:
            why.append(f"refused run changed earlier outputs: {', '.join(changed[:3])}")
    if "keep_outputs" in checks and before_tree:
        gone = [k for k in before_tree if not (outdir / k).exists()]
        if gone:
            why.append(f"earlier outputs gone: {', '.join(gone[:4])}")
        rows = history_rows(outdir)
        if before_rows and (rows is None or rows < before_rows - 1):
            why.append(f"history rows {before_rows} -> {rows}")
    # The folders of the runs: the output folder, or a sweep's or validation's run folders (those that ran).
    runs = [outdir]
    if cmd_text.split()[1:2] and cmd_text.split()[1] in ("sweep", "validate") and outdir.is_dir():
        runs = [f for f in sorted(outdir.iterdir()) if (f / "history.csv").is_file()]
    # An interrupted run (130) keeps its summary and checkpoint; a full disk (1) has no room for them.
    if (expect == "stop" and rc == 130) or "summary" in checks:
        for name, key in (("summary.json", "summary"), ("checkpoint.pkl", "checkpoint")):
            for run in runs:
                if (key in checks or expect == "stop") and not (run / name).exists():
                    why.append(f"no {run.relative_to(d)}/{name}")
    lost = list(why)
    soft = []
    if "status_final" in checks or expect == "stop":
        st = outdir / "status.json"
        if st.exists():
            try:
                rec = json.loads(st.read_text())
                s = rec.get("state", rec.get("status"))
            except ValueError:
                s = "unreadable"
            if s in (None, "running", "unreadable"):
                soft.append(f"status.json {s}")
    if "no_lock" in checks or expect == "stop":
        locks = [str(p.relative_to(d)) for p in d.rglob(".crackle.lock")]
        if locks:
            soft.append(f"stale lock {locks[0]}")
    if "prompt_exit" in checks and after_sig is not None and after_sig > 5:
        soft.append(f"exited {after_sig:.0f} s after the signal")
    if "examples_whole" in checks:
        cut = [ln.split()[0] for ln in out.splitlines()
               if ln.strip() and not re.search(r"[.)\]:!?\"]\s*$", ln)]
        if cut:
            soft.append(f"descriptions cut: {', '.join(cut)}")
    if "history_monotonic" in checks:
        h = outdir / "history.csv"
        if h.exists():
            lines = h.read_text().splitlines()[1:]
            ts, ncol, bad = [], len(h.read_text().splitlines()[0].split(",")), 0
            for ln in lines:
                parts = ln.split(",")
                if len(parts) != ncol:
                    bad += 1
                    continue
                try:
                    ts.append(float(parts[0]))
                except ValueError:
                    bad += 1
            if bad or any(b <= a for a, b in zip(ts, ts[1:])):
                soft.append(f"history.csv: {bad} malformed rows, "
                            f"{sum(b <= a for a, b in zip(ts, ts[1:]))} non-increasing times")
                lost.append("history.csv torn/out of order")
    if "msg_short" in checks and len(err) > 2000:
        soft.append(f"message {len(err)} characters")
    warned = bool(inp.get("warn")) and re.search(inp["warn"], text, re.I | re.M) is not None
    msg_ok = (not inp.get("msg")) or re.search(inp["msg"], text, re.I) is not None
    if "Traceback" in text:
        cls = "traceback"
    elif lost:
        cls = "lost data"
    elif rc is None:
        cls = "timeout"
    elif rc < 0 or rc > 200:
        cls = "killed"
    elif expect == "refuse" and rc == 0 and not warned:
        cls = "silent"
    elif expect == "refuse" and rc == 0 and warned:
        cls = "clean" if not soft else "unclear"
        soft.append("warned, ran")
    elif expect == "refuse":
        cls = "clean" if rc == 2 and msg_ok and not soft else "unclear"
    elif expect == "run":
        cls = "clean" if rc == 0 and msg_ok and not soft else "unclear"
    elif expect == "stop":
        cls = "clean" if rc in (130, 1, 3, 0) and not soft else "unclear"
    else:  # either
        cls = "clean" if rc in (0, 2) and msg_ok and not soft else "unclear"
    if not msg_ok:
        soft.append(f"message lacks /{inp['msg']}/")
    tb = ""
    if "Traceback" in text:
        tail = [ln for ln in text.splitlines() if ln.strip()]
        tb = next((ln for ln in reversed(tail) if re.match(r"^\w*(Error|Exception|Interrupt)\b|^\w+Error:", ln.strip())), tail[-1] if tail else "")
    return {
        "id": iid, "item": inp["item"], "command": cmd_text, "expect": expect,
        "exit": "timeout" if rc is None else rc, "class": cls, "wall_s": round(wall, 1),
        "message": (tb.strip() if tb else first_message(out, err))[:300],
        "notes": "; ".join(lost + soft + notes),
        "stderr_tail": "\n".join(err.strip().splitlines()[-6:])[-1500:],
        "stdout_tail": "\n".join(out.strip().splitlines()[-4:])[-800:],
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", default=str(HERE / "inputs.toml"))
    ap.add_argument("--only", default="")
    ap.add_argument("--items", default="")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "crackle-battery" / "report.md"))
    ap.add_argument("--src", default=str(REPO / "src"))
    ap.add_argument("--work", default=str(Path(tempfile.gettempdir()) / "crackle-battery" / "runs"))
    ap.add_argument("--timeout", type=float, default=120.0)
    args = ap.parse_args(argv)
    args.src = str(Path(args.src).resolve())
    examples = Path(args.src) / "crackle" / "examples"
    inputs = tomllib.loads(Path(args.inputs).read_text())["input"]
    ids = [i["id"] for i in inputs]
    dup = {i for i in ids if ids.count(i) > 1}
    if dup:
        raise SystemExit(f"duplicate ids: {sorted(dup)}")
    if args.only:
        want = set(args.only.split(","))
        unknown = want - set(ids)
        if unknown:
            raise SystemExit(f"unknown ids: {sorted(unknown)}")
        inputs = [i for i in inputs if i["id"] in want]
    if args.items:
        items = {int(x) for x in args.items.split(",")}
        inputs = [i for i in inputs if i["item"] in items]
    Path(args.work).mkdir(parents=True, exist_ok=True)
    results = []
    t0 = time.time()
    with cf.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        futs = {ex.submit(run_input, i, args, examples): i for i in inputs}
        for fut in cf.as_completed(futs):
            try:
                r = fut.result()
            except Exception as e:  # the battery's own failure: report it, go on
                i = futs[fut]
                r = {"id": i["id"], "item": i["item"], "command": str(i.get("args", i.get("shell"))),
                     "expect": i["expect"], "exit": "-", "class": "battery error", "wall_s": 0,
                     "message": f"{type(e).__name__}: {e}", "notes": "", "stderr_tail": "", "stdout_tail": ""}
            results.append(r)
            print(f"[{len(results)}/{len(inputs)} {time.time() - t0:5.0f}s] {r['id']:32s} "
                  f"exit {str(r['exit']):>7s} {r['class']:10s} {r['message'][:90]}", flush=True)
    order = {i["id"]: n for n, i in enumerate(inputs)}
    results.sort(key=lambda r: order[r["id"]])
    counts = {}
    for r in results:
        counts[r["class"]] = counts.get(r["class"], 0) + 1
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out.with_suffix(".csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(results[0].keys()) if results else ["id"])
        w.writeheader()
        w.writerows(results)
    out.with_suffix(".json").write_text(json.dumps(results, indent=1))

    def cell(s):
        return str(s).replace("|", "\\|").replace("\n", " ")

    lines = [f"# crackle bad-input battery ({len(results)} inputs, {time.time() - t0:.0f} s, src {args.src})", "",
             "counts: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), "",
             "| id | item | command | expected | exit | class | message | notes |", "|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append("| " + " | ".join(cell(r[k]) for k in
                                        ("id", "item", "command", "expect", "exit", "class", "message", "notes")) + " |")
    out.write_text("\n".join(lines) + "\n")
    print("\ncounts per class:")
    for k, v in sorted(counts.items()):
        print(f"  {k:12s} {v}")
    print(f"report: {out} (and .csv, .json)")


if __name__ == "__main__":
    main()
