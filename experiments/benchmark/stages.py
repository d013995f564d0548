"""What the benchmark measures, one stage at a time (the predictor of Sec. III-B/C, III-D).

Stages and their peers:

* ``train``: samples/s of one optimisation step of the repeatability predictor (masked MSE
  of Sec. III-C, global-norm clipping, AdamW), ours (``rp_jax.train``) against the same
  network in PyTorch (``torch_reference``).
* ``predict``: samples/s of batched prediction, numpy in and numpy out.
* ``match``: query x database descriptor pairs per second of the ground-truth matcher
  (``rp_jax.groundtruth.matching.match_all_pairs``, Sec. III-D steps 1-2) against
  ``cv2.BFMatcher(cv2.NORM_L2).knnMatch(k=2)`` + ratio test, results checked identical.
* ``groundtruth``: wall time and peak memory of labelling one viewpoint as its number of
  images grows (no peer).

Model stages run each configuration in its own *worker* process (``worker.py``): JAX's
device count and XLA flags are fixed when JAX initialises, so they cannot change within a
process. The workers are started together, compile and warm up, and then the orchestrator
asks them for one timed measurement each in turn, round after round (A B C A B C ...), so
that load from other users of the machine falls on all of them alike.

Everything that touches JAX or PyTorch runs inside a worker; the orchestrator imports
neither.

One module each: ``config`` (sizes, variants), ``stats`` (median, pairwise ratio, CPU
peak), ``model_benches`` (what a worker runs), ``orchestration`` (workers and their
protocol), and the stages ``model_stage``, ``match_stage``, ``groundtruth_stage`` (and
``mapsum_stages`` for Sec. V). This module is their index: the names the driver
(``run.py``), the worker and the tests use.
"""

from __future__ import annotations

from experiments.benchmark.config import (
    OURS_DEFAULT,
    PEER_DEFAULT,
    PROTOCOL_PREFIX,
    SIZES,
    STAGE_VARIANTS,
    VARIANTS,
    Variant,
)
from experiments.benchmark.groundtruth_stage import groundtruth_once, run_groundtruth_stage
from experiments.benchmark.match_stage import run_match_stage, synthetic_descriptors
from experiments.benchmark.model_benches import ModelBench, check_torch_equals_jax, make_bench
from experiments.benchmark.model_stage import run_model_stage
from experiments.benchmark.orchestration import Worker, worker_env
from experiments.benchmark.stats import cpu_peak, pairwise_ratio, summarize_samples

__all__ = [
    "OURS_DEFAULT",
    "PEER_DEFAULT",
    "PROTOCOL_PREFIX",
    "SIZES",
    "STAGE_VARIANTS",
    "VARIANTS",
    "ModelBench",
    "Variant",
    "Worker",
    "check_torch_equals_jax",
    "cpu_peak",
    "groundtruth_once",
    "make_bench",
    "pairwise_ratio",
    "run_groundtruth_stage",
    "run_match_stage",
    "run_model_stage",
    "summarize_samples",
    "synthetic_descriptors",
    "worker_env",
]
