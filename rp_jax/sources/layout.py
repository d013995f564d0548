"""Shared bookkeeping of the dataset readers: layout errors, slot assignment, counting.

Sec. III-D of the paper groups the images of each viewpoint into cycles c_1..c_M and
assigns each image to a timestamp t_j. Every reader in ``rp_jax.sources`` does this the
same way, here:

* A capture's slot j comes from ``TimeSchedule.slot_of`` on its local wall-clock time (or
  from a per-session override, e.g. RobotCar's Table I). Captures farther than the
  schedule's tolerance from every timestamp are dropped and *counted*, never snapped.
* Cycles are renumbered 0..M-1 *per viewpoint*, in time order, by one of two rules:

  - ``"calendar"``: the cycle is the calendar day (day cycle) or year (year cycle) given by
    ``slot_of``. Webcam Clip Art (M = 4 days) uses this.
  - ``"session_rank"``: captures are grouped into *sessions* (one traversal or one capture
    day); the k-th session of a viewpoint that falls on slot j (in time order) is cycle k.
    With the paper's setups (RobotCar Table I: one traversal per hourly slot; CMU Seasons:
    one capture date per paper date) this gives M = 1 although the sessions lie on
    different calendar days or years, as the paper states.

A reader that is handed a folder in another layout raises ``LayoutError`` naming what it
looked for and what was missing.
"""

from __future__ import annotations

import collections
import contextlib
import csv
import dataclasses
import datetime as dt
import logging
import zoneinfo
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Literal

from rp_jax import categories
from rp_jax.schedule import TimeSchedule
from rp_jax.sources.capture import Capture

__all__ = [
    "CycleRule",
    "DROP_REASONS",
    "LayoutError",
    "ReadCounts",
    "assign_slots",
    "keep_nearest_per_slot",
    "mixed_sizes_message",
    "read_name_time_csv",
    "require_layout",
    "segmentation_path",
    "zone",
]

log = logging.getLogger(__name__)

CycleRule = Literal["calendar", "session_rank"]


class LayoutError(ValueError):
    """A folder is not in the layout a reader expects.

    The message names the root, the files or patterns looked for, and those missing.
    """


def require_layout(
    dataset: str, root: Path, expected: Sequence[str], missing: Sequence[str]
) -> None:
    """Raise ``LayoutError`` if anything in ``missing`` is non-empty.

    Args:
      dataset: the dataset's name for the message (``"Extended CMU Seasons"``).
      root: the folder given to the reader.
      expected: every path or glob pattern the reader looks for, relative to ``root``.
      missing: the subset of ``expected`` (or a more precise description) not found.
    """
    if not missing:
        return
    raise LayoutError(
        f"{root} is not a {dataset} layout: missing {'; '.join(missing)}. "
        f"Expected {', '.join(f'<root>/{e}' for e in expected)}"
    )


def zone(name: str) -> zoneinfo.ZoneInfo:
    """The IANA time zone ``name``, with an error naming it if unknown."""
    try:
        return zoneinfo.ZoneInfo(name)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError) as err:
        raise ValueError(f"unknown time zone {name!r} (expected an IANA name)") from err


def read_name_time_csv(path: Path, parse: Callable[[str], dt.datetime]) -> dict[str, dt.datetime]:
    """Image name -> time from a ``name,datetime`` CSV, each time read by ``parse``.

    A first row naming the columns (``name`` and ``datetime``, ``time`` or ``date``) is
    optional; blank lines and lines starting with ``#`` are skipped.

    Raises:
      LayoutError: naming the file and the first row that is not ``name,datetime``.
    """
    with Path(path).open(newline="") as f:
        rows = list(csv.reader(f))
    name_col, time_col = 0, 1
    if rows and any(c.strip().lower() == "name" for c in rows[0]):
        header = [c.strip().lower() for c in rows[0]]
        name_col = header.index("name")
        time_col = next((header.index(k) for k in ("datetime", "time", "date") if k in header), -1)
        if time_col < 0:
            raise LayoutError(f"{path}: header {rows[0]} has no 'datetime' column")
        rows = rows[1:]
    out: dict[str, dt.datetime] = {}
    for line_no, row in enumerate(rows, start=1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        try:
            out[row[name_col].strip()] = parse(row[time_col])
        except (IndexError, ValueError) as err:
            raise LayoutError(
                f"{path}: row {line_no} {row} is not 'name,datetime' ({err})") from err
    return out


# Reasons a reader drops an input file, in the order its summary lists them.
DROP_REASONS = ("unreadable", "no_time", "no_pose", "no_viewpoint", "unassigned", "extra_in_slot")
# Reasons that mean the input is not what the layout promises (the summary is a warning).
_SUSPECT_REASONS = ("unreadable", "no_time")
# How many names of each reason the summary shows.
_NAMES_SHOWN = 5


@dataclasses.dataclass
class ReadCounts:
    """What a reader saw, for the summary it logs: every dropped input counted by reason.

    Attributes:
      dataset: name used in the log line.
      read: image files found in the layout.
      unreadable: files whose header could not be read (corrupt, truncated, empty).
      no_time: files with no capture time (bad name, not in the metadata CSV).
      no_pose: files without a pose where one is needed (CMU, RobotCar).
      no_viewpoint: posed files outside every viewpoint.
      unassigned: captures farther than the tolerance from every timestamp.
      extra_in_slot: captures dropped because another one of the same (viewpoint, cycle,
        slot) lay nearer the timestamp (only where a reader keeps one per slot).
      kept: captures returned.
      dropped: reason -> the files dropped for it (``drop``), named in the summary.
    """

    dataset: str
    read: int = 0
    unreadable: int = 0
    no_time: int = 0
    no_pose: int = 0
    no_viewpoint: int = 0
    unassigned: int = 0
    extra_in_slot: int = 0
    kept: int = 0
    dropped: dict[str, list[str]] = dataclasses.field(default_factory=dict)

    def drop(self, reason: str, what: object) -> None:
        """Count one input dropped for ``reason`` (one of ``DROP_REASONS``) and name it."""
        if reason not in DROP_REASONS:
            raise ValueError(f"unknown drop reason {reason!r}; expected one of {DROP_REASONS}")
        setattr(self, reason, getattr(self, reason) + 1)
        self.dropped.setdefault(reason, []).append(str(what))

    def summary(self) -> str:
        """One line: the counts by reason, then the files dropped for each reason."""
        parts = [f"{self.read} read"]
        parts += [f"{getattr(self, name)} {name.replace('_', ' ')}" for name in DROP_REASONS]
        parts.append(f"{self.kept} kept")
        line = f"{self.dataset}: {', '.join(parts)}"
        for reason in DROP_REASONS:
            names = self.dropped.get(reason)
            if not names:
                continue
            shown = ", ".join(names[:_NAMES_SHOWN])
            more = len(names) - _NAMES_SHOWN
            line += f"; {reason.replace('_', ' ')}: {shown}" + (f" and {more} more" if more > 0
                                                                  else "")
        return line

    def log_summary(self) -> None:
        """Log ``summary``: a warning if files were unreadable or had no time, else INFO."""
        suspect = any(getattr(self, name) for name in _SUSPECT_REASONS)
        log.log(logging.WARNING if suspect else logging.INFO, "%s", self.summary())


def assign_slots(
    captures: Iterable[Capture],
    schedule: TimeSchedule,
    *,
    cycle_rule: CycleRule = "calendar",
    session_of: Callable[[Capture], Hashable] | None = None,
    slot_override: Callable[[Capture], int | None] | None = None,
    counts: ReadCounts | None = None,
) -> list[Capture]:
    """Assign (cycle k, slot j) to each capture (Sec. III-D); drop and count the rest.

    Args:
      captures: captures with tz-aware local times and their viewpoint set.
      schedule: the T timestamps of a cycle.
      cycle_rule: ``"calendar"`` or ``"session_rank"`` (see the module docstring).
      session_of: the session key of a capture for ``"session_rank"``; defaults to the
        capture's local date.
      slot_override: returns a slot for captures whose slot is fixed by hand (RobotCar's
        Table I), or None to use ``schedule.slot_of``.
      counts: incremented in ``unassigned``.

    Returns:
      The assigned captures, sorted by (viewpoint, time, image_id), cycles 0-based per
      viewpoint.
    """
    session_of = session_of or (lambda c: c.time.date())
    raw: list[tuple[Capture, int, int]] = []  # capture, calendar cycle, slot
    for capture in captures:
        override = slot_override(capture) if slot_override else None
        calendar = schedule.slot_of(capture.time, strict=False)
        if override is not None:
            if not 0 <= override < schedule.num_timestamps:
                raise ValueError(
                    f"slot override {override} for {capture.image_path} outside 0.."
                    f"{schedule.num_timestamps - 1} of schedule {schedule.name!r}"
                )
            cycle = calendar[0] if calendar else _calendar_cycle(capture, schedule)
            raw.append((capture, cycle, override))
        elif calendar is None:
            if counts is not None:
                counts.drop("unassigned", capture.image_path)
        else:
            raw.append((capture, calendar[0], calendar[1]))

    by_viewpoint: dict[str, list[tuple[Capture, int, int]]] = collections.defaultdict(list)
    for item in raw:
        by_viewpoint[item[0].viewpoint].append(item)

    out: list[Capture] = []
    for viewpoint in sorted(by_viewpoint):
        items = sorted(by_viewpoint[viewpoint], key=lambda it: (it[0].time, it[0].image_id))
        if cycle_rule == "calendar":
            order = {c: k for k, c in enumerate(sorted({it[1] for it in items}))}
            out.extend(cap.with_slot(order[cyc], slot) for cap, cyc, slot in items)
        elif cycle_rule == "session_rank":
            # The k-th session (in time order of its first capture) landing on slot j.
            rank: dict[tuple[Hashable, int], int] = {}
            taken: dict[int, int] = collections.Counter()
            for cap, _, slot in items:
                key = (session_of(cap), slot)
                if key not in rank:
                    rank[key] = taken[slot]
                    taken[slot] += 1
                out.append(cap.with_slot(rank[key], slot))
        else:
            raise ValueError(f"cycle_rule must be 'calendar' or 'session_rank', got {cycle_rule!r}")
    return out


def _calendar_cycle(capture: Capture, schedule: TimeSchedule) -> int:
    """The calendar day ordinal or year of a capture (for hand-assigned slots)."""
    return capture.time.date().toordinal() if schedule.cycle == "day" else capture.time.year


def keep_nearest_per_slot(
    captures: Sequence[Capture], schedule: TimeSchedule, counts: ReadCounts | None = None
) -> list[Capture]:
    """Keep, per (viewpoint, cycle, slot), the capture nearest its timestamp.

    A webcam taking a frame every few minutes has several frames within the tolerance of one
    timestamp; the repeatability vector has one entry per timestamp, so one frame is kept.
    Ties go to the earlier capture. Dropped captures are counted in ``extra_in_slot``.
    """
    best: dict[tuple[str, int, int], tuple[float, Capture]] = {}
    for cap in captures:
        key = (cap.viewpoint, cap.cycle, cap.slot)
        gap = _gap_to_slot(cap, schedule)
        if key not in best or (gap, cap.time) < (best[key][0], best[key][1].time):
            best[key] = (gap, cap)
    kept = {id(c) for _, c in best.values()}
    if counts is not None:
        for c in captures:
            if id(c) not in kept:
                counts.drop("extra_in_slot", c.image_path)
    return [c for c in captures if id(c) in kept]


def _gap_to_slot(capture: Capture, schedule: TimeSchedule) -> float:
    offset = schedule.offset_of(capture.time)
    target = schedule.offsets[capture.slot]
    d = abs(offset - target) % schedule.period
    return float(min(d, schedule.period - d))


def segmentation_path(root: Path, image_path: Path, *alternatives: Path) -> Path | None:
    """The category map of an image if one exists (``rp_jax.categories`` convention).

    Looks for ``<root>/segmentation/<image path relative to root>.png`` and then each of
    ``alternatives`` (paths relative to ``<root>/segmentation``).
    """
    seg_root = Path(root) / categories.SEGMENTATION_DIR
    if not seg_root.is_dir():
        return None
    candidates = []
    with contextlib.suppress(ValueError):
        candidates.append(Path(image_path).relative_to(root).with_suffix(".png"))
    candidates.extend(alternatives)
    for rel in candidates:
        path = seg_root / rel
        if path.is_file():
            return path
    return None


def mixed_sizes_message(what: str, by_size: Mapping[tuple[int, int], Sequence[str]]) -> str:
    """The error of images of several sizes where a static camera needs one, naming files.

    Args:
      what: the viewpoint or folder, for the message.
      by_size: (W, H) -> the files of that size.
    """
    ordered = sorted(by_size.items(), key=lambda kv: -len(kv[1]))
    parts = []
    for (w, h), names in ordered:
        shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        parts.append(f"{len(names)} at {w}x{h} ({shown})")
    return (f"{what} has images of {len(by_size)} sizes: {'; '.join(parts)}. A static camera's "
            "< 5 px check compares pixel positions, so they must share one size: resize the "
            "odd ones to the others' size or move them out")
