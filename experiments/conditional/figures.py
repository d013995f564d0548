"""One held-out point's predicted repeatability over a whole year, hour by hour (issue 17).

The conditional predictor takes any instant as its target, so a point's repeatability is a
function of the day of the year and the hour, not a vector of T slots. For one held-out
point of a fold this draws that function (every hour of a year at its viewpoint's place
and clock) for each trained variant, with the night (sun below the horizon) outlined; a
variant that reads the weather is drawn under a clear sky.
"""

from __future__ import annotations

import datetime as dt
import zoneinfo
from pathlib import Path

import numpy as np

__all__ = ["year_of_one_point"]

_CLEAR = {"cloud_cover": 0.05, "precipitation": 0.0, "snow_cover": 0.0, "weather": 0}


def _year_moments(zone: str, place, year: int = 2013, with_year: bool = False
                  ) -> dict[str, np.ndarray]:
    from rp_jax.conditional import inputs

    tz = zoneinfo.ZoneInfo(zone) if zone else dt.UTC
    start = dt.datetime(year, 1, 1, tzinfo=tz)
    times = [start + dt.timedelta(days=d, hours=h) for d in range(365) for h in range(24)]
    return inputs.moment_at(times, place=place, weather=_CLEAR, with_year=with_year)


def year_of_one_point(config, run_dir: Path, variants, held, sidecar, out: Path) -> Path:
    """Draw ``out`` (PNG): one row per variant, probability by day (x) and hour (y).

    Args:
      config: the run's config (``experiments.conditional.config``).
      run_dir: the fold's folder (``<variant>/params.msgpack`` in it).
      variants: the variants (tuples of conditions) trained there.
      held: the fold's held-out ``PairArrays`` (with ``label``).
      sidecar: viewpoint -> its sidecar (place and zone of the point's viewpoint).
    """
    import jax
    import jax.numpy as jnp
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.conditional import config as config_lib
    from experiments.conditional.variants import load_params, network, variant_name
    from rp_jax import files
    from rp_jax.model import preprocess_patches

    p = held.points
    spread = np.where(p["label_mask"], p["label"], np.nan)
    index = int(np.nanargmax(np.nanstd(spread, axis=1)))  # the point whose y^j varies most
    side = sidecar[held.viewpoints[p["table"][index]]]
    place = (float(side["image_latitude"][0]), float(side["image_longitude"][0]))
    year = _year_moments(str(side["timezone"]), place,  # a decay basis reads the year too
                         with_year=bool(config_lib.decay_time_scales(config)))
    capture = {k[len("capture_"):]: jnp.asarray(v[index:index + 1])
               for k, v in p.items() if k.startswith("capture_")}
    target = {k: jnp.asarray(v)[None] for k, v in year.items()}
    fig, axes = plt.subplots(len(variants), 1, figsize=(9, 2.2 * len(variants) + 0.6),
                             squeeze=False)
    night = (year["sun_elevation_deg"] < 0).reshape(365, 24).T
    for ax, conditions in zip(axes[:, 0], variants):
        name = variant_name(conditions)
        net = network(config, conditions)
        params = load_params(net, run_dir / name / "params.msgpack")
        logits = jax.jit(net.apply)({"params": params},
                                    preprocess_patches(jnp.asarray(p["patch"][index:index + 1])),
                                    jnp.asarray(p["xy_normalized"][index:index + 1]), capture,
                                    target, jnp.asarray(p["category"][index:index + 1]))
        prob = np.asarray(jax.nn.sigmoid(logits))[0].reshape(365, 24).T
        image = ax.imshow(prob, aspect="auto", origin="lower", vmin=0, vmax=1, cmap="viridis",
                          extent=(0, 365, 0, 24))
        ax.contour(np.arange(365) + 0.5, np.arange(24) + 0.5, night, levels=[0.5],
                   colors="white", linewidths=0.6)
        ax.set_ylabel("hour")
        ax.set_title(f"{name}" + (" (clear sky)" if "weather" in conditions else ""),
                     fontsize=9)
        fig.colorbar(image, ax=ax, label="P(re-detected)")
    axes[-1, 0].set_xlabel("day of the year (white lines: sunrise and sunset)")
    cap_time = f"{int(p['capture_hour'][index]):02d}:{int(p['capture_minute'][index]):02d}"
    fig.suptitle(f"One held-out point ({held.viewpoints[p['table'][index]]}, captured "
                 f"{int(p['capture_day'][index])}/{int(p['capture_month'][index])} {cap_time}):"
                 " predicted repeatability at every hour of a year", fontsize=10)
    fig.tight_layout()
    with files.replacing(out, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return out
