"""A stand-in driver for tests/experiments/test_map_summarization_seed_processes.py: its
``evaluate_seed`` writes a seed's file, ends its process abruptly for seed 13, and for seeds
from 90 on writes ``started<S>`` (its process id) and sleeps a minute."""

import json
import os
import signal
import time


def evaluate_seed(config, workdir, seed, fingerprint):
    if seed == 13:
        os.kill(os.getpid(), signal.SIGKILL)
    if seed >= 90:
        (workdir / f"started{seed}").write_text(str(os.getpid()))
        time.sleep(60)
    out = workdir / f"seed{seed}"
    out.mkdir(parents=True, exist_ok=True)
    (out / "seed.json").write_text(json.dumps({"fingerprint": fingerprint, "pid": os.getpid()}))
