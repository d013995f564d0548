"""The paper's three time representations (Sec. III-B), as names: which fields each reads.

Constants only, without JAX, so that the commands can print them in ``--help`` before
anything heavy is imported; ``rp_jax.time_encoding`` encodes them and re-exports these.
"""

from __future__ import annotations

__all__ = ["ENCODINGS", "FIELDS", "READS"]

# Which fields each of the paper's three representations uses.
FIELDS = {
    "time_of_day": ("hour", "minute"),
    "day_of_year": ("day", "month"),
    "hour_of_year": ("hour", "minute", "day", "month"),
}
ENCODINGS = ("raw", "cyclic")
# What each representation reads of a time, in words: what the commands print and each
# shipped model's model.json says (a time-of-day model ignores the date, and the reverse).
READS = {
    "time_of_day": "the time of day (hour and minute), not the date",
    "day_of_year": "the day of the year (day and month), not the hour",
    "hour_of_year": "the time of day and the day of the year",
}
