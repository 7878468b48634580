"""Results identical before and after a refactoring: snapshot the outputs of fixed runs, compare two snapshots.

Runs, in a scratch folder, with the r360gpu that ``PYTHONPATH`` (or the installed package) gives:

* ``demo``: ``r360gpu demo`` on a small procedural benchmark (2 scenes x 5 methods, 4 views, 160x120),
  bootstrap and permutations cut down so it takes well under a minute on a CPU;
* ``public-compat``: ``r360gpu score --compat public tests/data/compat_public/office_chair`` (the public
  Remove360 layout; its adversarial depth PNGs are only readable the public scripts' way, so compat only);
* ``public-default``: the same folder with ``--compat public-default``;
* ``demo-whatif``: the demo with ``--orbit 12 --prune-residuals 0.1`` and ``--layouts`` (the orbit and the
  pruned what-ifs in results.json; its public Remove360 folders are what the next three runs score);
* ``layout-compat`` / ``layout-default``: one of those public-layout folders in both compat modes;
* ``benchmark``: ``r360gpu score --benchmark`` on the root of those folders (every method of the scene).

The snapshot of a run keeps ``results.json`` without its timing fields (``created``, ``timing``) and with
the scratch folder and checkout in its source paths replaced by ``<WORK>`` / ``<ROOT>``, the sha256 of
``results.csv``, ``tables.md`` and ``tables.tex``, and of every picture and plot PNG, and the order
results.json lists its keys in (``key_order``: every object's dotted key paths, in document order, so
two documents that hold the same values in another order differ too).  Left out:
``report.html`` (it prints the run's timing) and the hidden per-view cache (its keys hold paths).

    python bench/results_equal.py snapshot before.json       # on the old tree
    python bench/results_equal.py snapshot after.json        # on the new tree
    python bench/results_equal.py compare before.json after.json [--allow scenes.*.probes]

``compare`` prints every differing path (``--allow`` names paths, ``*`` matching one key, that may differ:
a field a change adds on purpose) and exits 1 when anything else differs.
"""
from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PUBLIC = ROOT / "tests" / "data" / "compat_public" / "office_chair"
STATS = ["--n-boot", "200", "--n-perm", "100", "--seed", "0", "--quiet"]
RUNS = {
    "demo": ["demo", "--n-views", "4", "--width", "160", "--height", "120", *STATS],
    "public-compat": ["score", "--compat", "public", str(PUBLIC), *STATS],
    "public-default": ["score", "--compat", "public-default", str(PUBLIC), *STATS],
    "demo-whatif": ["demo", "--n-views", "4", "--width", "160", "--height", "120", "--layouts", "--orbit", "12",
                    "--prune-residuals", "0.1", *STATS],
    # {work}: the scratch folder, where demo-whatif (run before these) wrote its layouts
    "layout-compat": ["score", "--compat", "public", "{work}/demo-whatif/layouts/public/floaters/room_sofa",
                      *STATS],
    "layout-default": ["score", "--compat", "public-default",
                       "{work}/demo-whatif/layouts/public/floaters/room_sofa", *STATS],
    "benchmark": ["score", "--benchmark", "{work}/demo-whatif/layouts/public", *STATS],
}
TIMING_KEYS = ("created", "timing")
#: Paths that name where a run happened, not what it computed: the scratch folder and the checkout.
_WHERE = [(re.compile(r"/[^\"]*?/r360-equal-[^/\"]+/"), "<WORK>/"),
          (re.compile(r"/[^\"]*?/tests/data/compat_public/"), "<ROOT>/tests/data/compat_public/")]


def normalise(run: dict) -> dict:
    """A run's snapshot without where it ran: source paths made relative to the scratch folder or the
    checkout, and hidden files (the per-view cache, whose keys hold those paths) left out."""
    text = json.dumps(run["results"])
    for pat, repl in _WHERE:
        text = pat.sub(repl, text)
    files = {k: v for k, v in run["files"].items() if not any(part.startswith(".") for part in k.split("/"))}
    results = json.loads(text)
    return {"results": results, "files": files, "key_order": key_order(results)}


def key_order(doc, path: str = "") -> list[str]:
    """Every object's keys as dotted paths, in the order the document lists them (list items by index)."""
    out: list[str] = []
    if isinstance(doc, dict):
        for k, v in doc.items():
            p = f"{path}.{k}" if path else str(k)
            out.append(p)
            out += key_order(v, p)
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += key_order(v, f"{path}[{i}]")
    return out


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _report_dir(out: Path) -> Path:
    return out / "report" if (out / "report" / "results.json").exists() else out


def snapshot_run(name: str, args: list[str], work: Path) -> dict:
    out = work / name
    args = [a.replace("{work}", str(work)) for a in args]
    cmd = [sys.executable, "-m", "r360gpu", *args[:1], "--out", str(out), *args[1:]]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy())
    if proc.returncode != 0:
        raise SystemExit(f"{name}: {' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    rep = _report_dir(out)
    results = json.loads((rep / "results.json").read_text())
    for k in TIMING_KEYS:
        results.pop(k, None)
    files = {p.relative_to(rep).as_posix(): _sha(p)
             for p in sorted(rep.rglob("*")) if p.is_file() and p.name != "report.html" and p.name != "results.json"}
    return normalise({"results": results, "files": files})


def _diff(a, b, path: str, out: list[str]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            p = f"{path}.{k}" if path else str(k)
            if k not in a:
                out.append(f"{p}: only after")
            elif k not in b:
                out.append(f"{p}: only before")
            else:
                _diff(a[k], b[k], p, out)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            _diff(x, y, f"{path}[{i}]", out)
    elif a != b:
        out.append(f"{path}: {json.dumps(a)[:80]} -> {json.dumps(b)[:80]}")


def _allowed(line: str, allow: list[str]) -> bool:
    path = line.split(":", 1)[0]
    parts = path.split(".")
    for pat in allow:
        pp = pat.split(".")
        if len(parts) >= len(pp) and all(fnmatch.fnmatchcase(x, y) for x, y in zip(parts, pp)):
            return True
    return False


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("snapshot")
    s.add_argument("out")
    s.add_argument("--runs", default=",".join(RUNS))
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    c.add_argument("--allow", action="append", default=[])
    a = ap.parse_args(argv)
    if a.cmd == "snapshot":
        with tempfile.TemporaryDirectory(prefix="r360-equal-") as tmp:
            snap = {name: snapshot_run(name, RUNS[name], Path(tmp)) for name in a.runs.split(",")}
        Path(a.out).write_text(json.dumps(snap, indent=1))  # not sorted: key_order keeps the document's
        for name, run in snap.items():
            print(f"{name}: results.json {len(json.dumps(run['results']))} chars, {len(run['files'])} files")
        return 0
    before, after = ({name: normalise(run) for name, run in json.loads(Path(p).read_text()).items()}
                     for p in (a.before, a.after))
    diffs: list[str] = []
    _diff(before, after, "", diffs)
    bad = [d for d in diffs if not _allowed(d.split(".", 2)[-1] if d.split(".")[1] == "results" else d, a.allow)]
    for name in sorted(set(before) | set(after)):
        n_files = len(after.get(name, {}).get("files", {}))
        mine = [d for d in diffs if d.startswith(name + ".")]
        print(f"{name}: results.json + {n_files} files compared, {len(mine)} differences"
              f" ({len([d for d in mine if d in bad])} not allowed)")
    for d in diffs:
        print(("  ALLOWED " if d not in bad else "  DIFF    ") + d)
    print("IDENTICAL" if not diffs else ("IDENTICAL except allowed fields" if not bad else "DIFFERENT"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
