"""Speed of rp_jax against what users would otherwise write: PyTorch and OpenCV.

``python -m experiments.benchmark`` times the repeatability predictor (Sec. III-B, III-C:
train step and batched prediction) against the same network in PyTorch, the ground-truth
matcher (Sec. III-D) against ``cv2.BFMatcher``, ground-truth labelling against the number
of images of a viewpoint, map summarization (Sec. V-A) against K-cover, and per-query
localization (Sec. V-B) against plain OpenCV; ``report.py`` writes the output.

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
protocol), the stages ``model_stage``, ``match_stage``, ``groundtruth_stage``,
``summarize_stage`` and ``localize_stage`` (Sec. V), and ``run.py``, which runs the stages
asked for and writes the report (``report.py``).
"""
