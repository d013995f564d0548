"""World seeds, label worlds and label slices made in several processes at once (a run's
``--processes``, ``config.map.processes``).

A map-summarization run evaluates each world seed on its own (``world.evaluate_world``:
the map, the queries and every row's summaries at every ratio) and writes the seed's
outcomes to ``<workdir>/seed<S>/seed.json`` under the run's fingerprint (the settings and
the trained models' weights); a run that finds a seed's file with its fingerprint reads it
instead of evaluating the seed again. The seeds are independent, and a seed's evaluation is
mostly one core's work (SIFT, 2D-3D matching, PnP-RANSAC), so on a machine with several
cores ``evaluate_in_processes`` evaluates the seeds a run lacks in that many spawned
processes, each of which writes its ``seed.json``; the run then reads them as it reads a
finished seed, in seed order. The outcomes are those of one process: each process loads
the run's trained models from the workdir (trained there before, by the run) and refuses
to evaluate if its fingerprint differs from the run's. The outcome scorer's label slices
and label worlds, cached the same way, are made with ``run_in_processes`` before the
scorers train (``outcome_labels.label_slice``, ``layout_outcomes.label_world``).

A driver module (``experiments.map_summarization.conditions``, ...) provides
``evaluate_seed(config, workdir, seed, fingerprint)``: load its models from ``workdir``,
check the fingerprint, evaluate the seed.
"""

from __future__ import annotations

import argparse
import importlib
import logging
from collections.abc import Callable, Sequence
from concurrent.futures import as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import ml_collections

from rp_jax import worker_processes

__all__ = ["SeedProcessError", "add_processes", "evaluate_in_processes", "missing_seeds",
           "outcome_settings", "run_in_processes"]

log = logging.getLogger(__name__)


class SeedProcessError(RuntimeError):
    """A process ended without finishing its job (killed, or out of memory)."""


def _processes(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1")
    return n


def add_processes(parser: argparse.ArgumentParser) -> None:
    """``--processes N`` of the map-summarization commands (``config.map.processes``): world
    seeds and label worlds evaluated at once, each in a process of its own."""
    parser.add_argument("--processes", type=_processes, default=None, metavar="N",
                        help="world seeds and label worlds evaluated at once, each in a "
                             "process of its own (config.map.processes, default 1; the "
                             "outcomes are the same; each process holds one world in memory)")


def outcome_settings(map_settings: dict) -> dict:
    """The map settings (``config.map.to_dict()``) that make a seed's outcomes, for its
    fingerprint: without the seed list and how many seeds run at once (``processes``), and
    with how many processes render a world (``workers``, whose images are the same for every
    count) at its default, 0, so that a seed evaluated with any count is found again."""
    settings = dict(map_settings)
    settings.pop("seeds", None)
    settings.pop("processes", None)
    if "workers" in settings:
        settings["workers"] = 0
    return settings


def missing_seeds(workdir: Path, seeds: Sequence[int], fingerprint: str) -> list[int]:
    """The seeds without a ``seed.json`` of ``fingerprint`` in ``workdir/seed<S>``."""
    from experiments.map_summarization.world import finished_seed  # the map stack: when needed

    out = []
    for s in seeds:
        try:
            done = finished_seed(Path(workdir) / f"seed{s}", fingerprint) is not None
        except (OSError, ValueError):  # a file cut short: evaluated again
            done = False
        if not done:
            out.append(int(s))
    return out


def _call(function: str, args: tuple) -> None:
    """In a spawned process: ``module:function(*args)``, with the commands' CPU set-up."""
    from rp_jax import platform
    from rp_jax import progress as progress_lib

    platform.configure_cpu()
    progress_lib.set_quiet()
    module, name = function.split(":")
    getattr(importlib.import_module(module), name)(*args)


def run_in_processes(function: str, jobs: Sequence[tuple], names: Sequence[str],
                     processes: int, *, workdir: Path, progress: bool = True) -> None:
    """``module:function(*job)`` for every job, ``processes`` at a time, each in a spawned
    process of its own (``names``: what each job is, for the progress line and errors).

    Raises:
      SeedProcessError: a process ended without finishing.
      Whatever a job raised, with a note naming it.
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    n = min(int(processes), len(jobs))
    try:
        # Spawned processes that exit with this one (a killed run must not leave them
        # evaluating: a world seed takes up to half an hour); Ctrl-C ends them at once.
        with worker_processes.process_pool(n) as pool, \
                tqdm(total=len(jobs), desc=f"{', '.join(names)} in {n} processes",
                     disable=not progress) as done:
            futures = {pool.submit(_call, function, tuple(job)): name
                       for job, name in zip(jobs, names)}
            for future in as_completed(futures):
                name = futures[future]
                try:
                    future.result()
                except BrokenProcessPool as e:  # every unfinished job's future says so
                    left = [futures[f] for f in futures
                            if not (f.done() and not f.cancelled() and f.exception() is None)]
                    raise SeedProcessError(
                        "a process ended before it finished (killed, or out of memory: each "
                        "process holds one world; try fewer --processes than "
                        f"{n}); not done: {', '.join(left)}; what finished is kept in "
                        f"{workdir} and a run started again goes on from it") from e
                except Exception as e:
                    e.add_note(f"({name}, in a process of its own)")
                    raise
                log.info("%s done in its process", name)
                done.update()
    except (KeyboardInterrupt, SystemExit):
        # Ctrl-C: the processes' jobs are not waited for (a world seed takes up to half an
        # hour); what finished is on disk and a run started again goes on from it.
        log.warning("interrupted: stopping %d processes; what finished is kept in %s", n,
                    workdir)
        raise


def evaluate_in_processes(driver: str, config: ml_collections.ConfigDict, workdir: Path,
                          seeds: Sequence[int], fingerprint: str, processes: int, *,
                          prepare: Callable[[int], object] | None = None,
                          progress: bool = True) -> list[int]:
    """Evaluate the ``seeds`` that lack their ``seed.json`` in ``processes`` spawned
    processes (``driver.evaluate_seed`` in each); returns the seeds evaluated.

    Nothing is done with one process or at most one missing seed (the caller evaluates in
    its own process, as always). ``prepare(seed)`` runs first in this process for every
    missing seed (e.g. rendering the seed's world with every core, which a process of the
    pool would do on one).

    Raises:
      SeedProcessError: a process ended without finishing.
      Whatever a process raised, with a note naming its seed.
    """
    todo = missing_seeds(workdir, seeds, fingerprint)
    if processes <= 1 or len(todo) <= 1:
        return []
    for s in todo:
        if prepare is not None:
            prepare(s)
    run_in_processes(f"{driver}:evaluate_seed",
                     [(config, Path(workdir), s, fingerprint) for s in todo],
                     [f"world seed {s}" for s in todo], processes, workdir=Path(workdir),
                     progress=progress)
    return todo
