"""World seeds evaluated in several processes at once (a run's ``--processes``).

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
to evaluate if its fingerprint differs from the run's.

A driver module (``experiments.map_summarization.conditions``, ...) provides
``evaluate_seed(config, workdir, seed, fingerprint)``: load its models from ``workdir``,
check the fingerprint, evaluate the seed.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import ml_collections

__all__ = ["SeedProcessError", "add_processes", "evaluate_in_processes", "missing_seeds"]

log = logging.getLogger(__name__)


class SeedProcessError(RuntimeError):
    """A seed's process ended without finishing (killed, or out of memory)."""


def _processes(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1")
    return n


def add_processes(parser: argparse.ArgumentParser) -> None:
    """``--processes N`` of the map-summarization commands: world seeds evaluated at once,
    each in a process of its own (``evaluate_in_processes``)."""
    parser.add_argument("--processes", type=_processes, default=1, metavar="N",
                        help="world seeds evaluated at once, each in a process of its own "
                             "(default 1; the outcomes are the same; each process holds one "
                             "world's map and queries in memory)")


def missing_seeds(workdir: Path, seeds: Sequence[int], fingerprint: str) -> list[int]:
    """The seeds without a ``seed.json`` of ``fingerprint`` in ``workdir/seed<S>``."""
    from experiments.map_summarization.world import SEED_FILE  # the map stack: when needed

    out = []
    for s in seeds:
        path = Path(workdir) / f"seed{s}" / SEED_FILE
        try:
            done = json.loads(path.read_text()).get("fingerprint") == fingerprint
        except (OSError, ValueError):
            done = False
        if not done:
            out.append(int(s))
    return out


def _evaluate(driver: str, config: ml_collections.ConfigDict, workdir: str, seed: int,
              fingerprint: str) -> int:
    """In a spawned process: the driver's ``evaluate_seed``."""
    from rp_jax import platform
    from rp_jax import progress as progress_lib

    platform.configure_cpu()
    progress_lib.set_quiet()
    importlib.import_module(driver).evaluate_seed(config, Path(workdir), seed, fingerprint)
    return seed


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
    from rp_jax.progress import bar as tqdm  # the one progress helper

    n = min(int(processes), len(todo))
    context = multiprocessing.get_context("spawn")  # JAX and OpenCV threads do not fork
    with ProcessPoolExecutor(max_workers=n, mp_context=context) as pool, \
            tqdm(total=len(todo), desc=f"seeds {todo} in {n} processes",
                 disable=not progress) as done:
        futures = {pool.submit(_evaluate, driver, config, str(workdir), s, fingerprint): s
                   for s in todo}
        for future in as_completed(futures):
            seed = futures[future]
            try:
                future.result()
            except BrokenProcessPool as e:  # every unfinished seed's future says so
                for f in futures:
                    f.cancel()
                left = missing_seeds(workdir, todo, fingerprint)
                raise SeedProcessError(
                    "a process evaluating the world seeds ended before it finished (killed, "
                    "or out of memory: each process holds one world; try fewer --processes "
                    f"than {n}); seeds {left} are not done, the others are kept in "
                    f"{workdir} and a run started again goes on from them") from e
            except Exception as e:
                for f in futures:
                    f.cancel()
                e.add_note(f"(world seed {seed}, evaluated in a process of its own)")
                raise
            log.info("seed %d evaluated in its process", seed)
            done.update()
    return todo
