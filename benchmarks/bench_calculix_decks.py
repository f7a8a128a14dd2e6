"""``qsma run`` on the CalculiX test decks that hold a ``*CONTACT PAIR``.

    python benchmarks/bench_calculix_decks.py FOLDER [--timeout 600] [--jobs 1]

FOLDER holds ``.inp`` decks (the ``test/`` folder of the CalculiX source distribution;
nothing is fetched here). Each deck with a ``*CONTACT PAIR`` is run as it is,
``qsma run DECK --out TMP --density RHO -q --no-plots --no-vtu``, in a process of its
own, with what a deck run takes by default (the probe at the node of largest modal
displacement, its deflection from 1e-6 to 1e-2 of the model's size). Most test decks
are static and give no ``*DENSITY``: ``--density`` gives steel's to the materials
without one, 7.85e-9 (t/mm^3) where the first ``*ELASTIC`` modulus is below 1e7 (a
deck in N and mm), else 7850 (kg/m^3). One line per deck: its outcome (ran, refused by
the deck reader with its first reasons, an input error, a failed analysis, timeout)
and the first line of the message; then the counts per outcome.
"""
from __future__ import annotations

import argparse
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import re
import subprocess
import sys
import tempfile


def outcome(deck: Path, timeout: float):
    """``(outcome, detail)`` of ``qsma run deck``."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "qsma", "run", str(deck), "--out", f"{tmp}/out", "-q",
               "--no-plots", "--no-vtu", "--density", str(steel_density(deck))]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return "timeout", f"over {timeout:g} s"
    err = [line for line in proc.stderr.splitlines() if line.startswith("qsma: ")]
    first_error = next((line for line in err if not line.startswith("qsma: warning")), "")
    if proc.returncode == 0:
        return "ran", f"{len(err)} note(s)"
    if "cannot be run as it is" in first_error:
        reasons = [line.strip() for line in proc.stderr.splitlines()[1:]
                   if line.startswith("  ")]
        return "refused", "; ".join(_short(r) for r in reasons[:3]) + \
            (f" (+{len(reasons) - 3})" if len(reasons) > 3 else "")
    if proc.returncode == 2:
        return "input error", _short(first_error.removeprefix("qsma: error: "))
    if "gross slip" in first_error:              # the levels before it are written
        return "gross slip", _short(first_error.removeprefix("qsma: analysis failed: "))
    return "failed", _short(first_error or proc.stderr.strip().splitlines()[-1])


def steel_density(deck: Path) -> float:
    """Steel's density in the deck's units, judged by its first *ELASTIC modulus."""
    m = re.search(rb"^\*elastic[^\n]*\n\s*([-+.\deE]+)", deck.read_bytes(), re.I | re.M)
    E = float(m.group(1)) if m else 2.1e5
    return 7.85e-9 if E < 1e7 else 7850.0


def _short(text: str) -> str:
    text = re.sub(r"(?<!\S)/\S*/", "", text)      # folders out of absolute paths
    return re.sub(r"^\S+\.inp, line \d+: ", "", text)[:160]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args(argv)
    decks = sorted(p for p in args.folder.glob("*.inp")
                   if re.search(rb"^\*contact pair", p.read_bytes(), re.I | re.M))
    with ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda d: outcome(d, args.timeout), decks))
    counts = Counter()
    for deck, (kind, detail) in zip(decks, results):
        counts[kind] += 1
        print(f"{deck.name:28s} {kind:12s} {detail}", flush=True)
    print()
    print(f"{'outcome':14s} decks")
    for kind, n in counts.most_common():
        print(f"{kind:14s} {n}")
    print(f"{'total':14s} {len(decks)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
