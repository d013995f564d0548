"""A stand-in driver for tests/experiments/test_map_summarization_seed_processes.py: its
``evaluate_seed`` writes a seed's file, or ends its process abruptly for seed 13."""

import json
import os
import signal


def evaluate_seed(config, workdir, seed, fingerprint):
    if seed == 13:
        os.kill(os.getpid(), signal.SIGKILL)
    out = workdir / f"seed{seed}"
    out.mkdir(parents=True, exist_ok=True)
    (out / "seed.json").write_text(json.dumps({"fingerprint": fingerprint, "pid": os.getpid()}))
