"""``train_under_delay.py --jobs N``: the study's seeds trained in N processes, then merged.

One PPO policy keeps one core busy, so the study's 25 trainings take a day on one core;
``--jobs`` splits the seeds round-robin over ``N`` child processes of the same script
(shard ``k`` trains ``seeds[k::N]``; only shard 0 evaluates the untrained and
hand-written policies), each writing ``<out>/shards/<k>`` and sharing one checkpoint
folder, then merges the shards into ``<out>`` (``--merge``). A rerun resumes: every
finished training is recorded in the checkpoint folder and not redone. The children's
progress lines are relayed, prefixed with their shard.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import threading
from pathlib import Path
from typing import IO

__all__ = ["run_jobs", "shard_argv"]

#: Options of the parent's command line a child gets in its own form.
_OWN = {"--jobs": 1, "--out": 1, "--seed-list": 1, "--checkpoints": 1, "--seeds": 1,
        "--skip-baselines": 0, "--ages-control": 0}


def shard_argv(argv: list[str], k: int, seeds: list[int], out: Path, checkpoints: str
               ) -> list[str]:
    """The command line of shard ``k`` (training ``seeds``) from the parent's ``argv``."""
    kept: list[str] = []
    it = iter(argv)
    for tok in it:
        name = tok.split("=", 1)[0]
        if name in _OWN:
            if _OWN[name] and "=" not in tok:
                next(it, None)
            continue
        kept.append(tok)
    kept += ["--seed-list", ",".join(map(str, seeds)), "--out", str(out),
             "--checkpoints", checkpoints]
    return kept + (["--skip-baselines"] if k > 0 else [])


def _relay(stream: IO[str], prefix: str) -> None:
    for line in stream:
        sys.stdout.write(f"{prefix}{line}")
        sys.stdout.flush()


def run_jobs(a: argparse.Namespace, argv: list[str], script: Path) -> int:
    """Train the seeds of ``a`` in ``a.jobs`` processes of ``script``, then merge.

    Returns:
        0, or the first failing shard's exit status (the shards that finished are
        merged all the same, so the outputs show what is done).
    """
    from sigma_lab.studies.delay_study import merge

    n = min(a.jobs, len(a.seed_ids))
    out = Path(a.out)
    shards = [out / "shards" / str(k) for k in range(n)]
    procs = []
    for k, d in enumerate(shards):
        cmd = [sys.executable, str(script),
               *shard_argv(argv, k, a.seed_ids[k::n], d, a.checkpoints)]
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True, bufsize=1)
        assert p.stdout is not None
        t = threading.Thread(target=_relay, args=(p.stdout, f"[shard {k}] "), daemon=True)
        t.start()
        procs.append((p, t))
    codes = []
    for p, t in procs:
        codes.append(p.wait())
        t.join()
    done = [str(d) for d in shards if (d / "summary.json").exists()]
    if done:
        a.merge = done
        merge(a)
    bad = [c for c in codes if c != 0]
    if bad:
        print(f"--jobs: {len(bad)} of {n} shards failed (exit {bad[0]}); merged the "
              f"{len(done)} with outputs; rerun to resume", file=sys.stderr)
    return bad[0] if bad else 0
