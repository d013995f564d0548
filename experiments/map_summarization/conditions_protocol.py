"""What the by-condition map-summarization run compares (``conditions.run``) and its report
reads (``conditions_report``): the groups of conditions, the primary comparison, the
exploratory contrasts and what each query reports finding in the full map."""

__all__ = ["CONDITION_GROUPS", "CONTRASTS", "EVIDENCE", "PRIMARY_GROUP", "PRIMARY_RATIOS",
           "PRIMARY_THRESHOLDS"]

# Exploratory paired comparisons beside K-cover's: (row, against).
CONTRASTS = (("outcome_top", "outcome_agnostic_top"),)
# The conditions by their light: both nights are lit by street lamps and windows only
# (the sun 20 deg below the horizon at their start), dawn and dusk by a low sun (about
# 7 deg; rp_jax.sources.robotcar_seasons.TRAVERSALS), the rest by day.
CONDITION_GROUPS = {
    "night": ("night", "night-rain"),
    "twilight": ("dawn", "dusk"),
    "day": ("overcast-summer", "overcast-winter", "rain", "snow", "sun"),
}
# The primary comparison (the matched oracles at night): its group, ratios and thresholds.
PRIMARY_GROUP = "night"
PRIMARY_RATIOS = ("0.8", "0.9")
PRIMARY_THRESHOLDS = ("0.5m_5deg", "5m_10deg")
# What a query finds in the full map, medians per condition (``conditions.query_evidence``):
# its SIFT keypoints, the map points it re-detects under its ground-truth pose, the full
# map's 2D-3D matches and PnP inliers.
EVIDENCE = ("keypoints", "redetected", "full_map_matches", "full_map_inliers")
