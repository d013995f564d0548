"""The conditional predictor with and without its long-term decay basis, on the years world.

``experiments.decay.measure`` shows that the ``webcam_years`` world's inlier fraction falls
with the years between capture and target. This asks whether a predictor learns that fall
(issue 17's long-term decay): the conditional predictor (``rp_jax.conditional``; time only,
no sun, weather or semantics) is trained on the per-pair outcomes of the training scenes
but one, with and without ``decay_time_scales`` (``inputs.DECAY_TIME_SCALES_YEARS``), and
scored on the held-out training scene, each training scene held out in turn (the held-out
pairs pooled, and per fold): per years-apart bin, the observed inlier fraction of its known
pairs against the mean predicted probability, and the BCE. The test scene is never
labelled nor used. Nothing is chosen on the held-out scene (fixed epochs).

The pairs are labelled as ``measure`` labels them (``viewpoint_outcomes``, the same cache),
``points_per_image`` records per image kept by the builder's rule
(``datasets.builder.select_records``), their patches cut from the images.

Run it as ``python -m experiments.decay --predict --size small``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from experiments.decay.measure import NUM_BINS, SECONDS_PER_YEAR, viewpoint_outcomes
from rp_jax import files
from rp_jax.sources.synthetic.presets import generate

__all__ = ["bin_table", "markdown", "pair_arrays", "run"]

log = logging.getLogger(__name__)

PRESET = "webcam_years"
VARIANTS = {"no decay": (), "decay basis": None}  # None: inputs.DECAY_TIME_SCALES_YEARS


def pair_arrays(per_viewpoint, captures, *, points_per_image: int, seed: int = 0):
    """``PairArrays`` (with ``year``) of ``(records, outcomes)`` of some viewpoints, and the
    years between each point's image and each target [N, K]."""
    from rp_jax.conditional import pairs
    from rp_jax.datasets import capture_conditions, registry
    from rp_jax.datasets.builder import select_records
    from rp_jax.groundtruth.viewpoint import attach_patches

    dataset = registry.get("webcam_clipart")
    columns, sidecar, rows, years = [], {}, [], []
    for records, outcomes in per_viewpoint:
        vp = str(records["viewpoint"][0])
        mine = [c for c in captures if str(c.viewpoint) == vp]
        kept = select_records({**records, "row": np.arange(len(records["xy"]))},
                              points_per_image, seed)
        kept = attach_patches(kept, mine, dataset.load_image)
        index = kept["row"]
        by_id = {str(c.image_id): c for c in mine}
        ordered = [by_id[str(i)] for i in np.asarray(outcomes["image_id"]).astype(str)]
        conditions = capture_conditions.capture_conditions(ordered, "webcam_clipart")
        side = {k: np.asarray(outcomes[k]) for k in ("image_id", "image_time", "image_slot",
                                                     "image_readable")}
        side.update({f"image_{k}": v for k, v in conditions.items()})
        side["outcome"] = np.asarray(outcomes["outcome"])[index]
        side["row_image"] = np.asarray(outcomes["row_image"])[index]
        sidecar[vp] = side
        columns.append(kept)
        rows.append(np.arange(len(index)))
        t = np.asarray(outcomes["image_unix_time"], np.float64)
        years.append(np.abs(t[None, :] - t[side["row_image"]][:, None]) / SECONDS_PER_YEAR)
    keys = ("patch", "xy_normalized", "category", "viewpoint")
    merged = {k: np.concatenate([c[k] for c in columns]) for k in keys}
    arrays = pairs.from_records(merged, sidecar, np.concatenate(rows), with_year=True)
    # from_records orders the tables by viewpoint; the rows keep the records' order.
    width = arrays.tables["valid"].shape[1]
    years_apart = np.full((len(arrays), width), np.nan)
    start = 0
    for y in years:
        years_apart[start:start + len(y), : y.shape[1]] = y
        start += len(y)
    return arrays, years_apart


def bin_table(probability, outcome, years_apart, num_bins: int = NUM_BINS) -> list[dict]:
    """Per whole-years-apart bin: known pairs, observed inlier fraction, mean predicted
    probability and BCE; a last row ``all``."""
    known = np.asarray(outcome) >= 0
    y = (np.asarray(outcome) == 1).astype(np.float64)
    q = np.clip(np.asarray(probability, np.float64), 1e-6, 1 - 1e-6)
    bce = -(y * np.log(q) + (1 - y) * np.log(1 - q))
    bins = np.rint(np.nan_to_num(years_apart, nan=-1)).astype(int)
    out = []
    for b in [*range(num_bins), "all"]:
        m = known & ((bins == b) if b != "all" else (bins >= 0) & (bins < num_bins))
        out.append({"years_apart": b, "pairs": int(m.sum()),
                    "observed": float(y[m].mean()) if m.any() else float("nan"),
                    "predicted": float(q[m].mean()) if m.any() else float("nan"),
                    "bce": float(bce[m].mean()) if m.any() else float("nan")})
    return out


def markdown(result: dict) -> str:
    """Observed vs predicted inlier % per years-apart bin, and BCE, per variant."""
    names = list(result["variants"])
    head = "| years apart | pairs | observed % | " + " | ".join(
        f"{n}: predicted % | {n}: BCE" for n in names) + " |"
    sep = "|---" + "|---:" * (2 + 2 * len(names)) + "|"

    def rows(variants: dict) -> list[str]:
        out = []
        for k, row in enumerate(variants[names[0]]["bins"]):
            cells = [str(row["years_apart"]), f"{row['pairs']:,}",
                     f"{100 * row['observed']:.1f}"]
            for n in names:
                r = variants[n]["bins"][k]
                cells += [f"{100 * r['predicted']:.1f}", f"{r['bce']:.4f}"]
            out.append("| " + " | ".join(cells) + " |")
        return out

    lines = ["Held-out training scenes pooled:", "", head, sep, *rows(result["variants"]), ""]
    for scene, fold in result.get("folds", {}).items():
        lines += [f"Held out {scene} ({fold['train_points']} training points, "
                  f"{fold['held_out_points']} held out):", "", head, sep,
                  *rows({n: fold[n] for n in names}), ""]
    return "\n".join(lines)


def plot(result: dict, out: Path) -> Path:
    """Observed and predicted inlier % against years apart, as a PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from rp_jax.plots import save_figure

    fig = Figure(figsize=(5.0, 3.4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    first = next(iter(result["variants"].values()))["bins"][:-1]
    x = np.array([r["years_apart"] for r in first], float)
    ax.plot(x, [100 * r["observed"] for r in first], "ko-", label="observed (held-out scenes)")
    for (name, v), style in zip(result["variants"].items(), ("s--", "^-")):
        ax.plot(x, [100 * r["predicted"] for r in v["bins"][:-1]], style,
                label=f"predicted, {name}")
    ax.set_xlabel("years between the point's image and the target image")
    ax.set_ylabel("inlier %")
    ax.set_ylim(0, None)
    ax.set_xticks(x)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, out)


def run(workdir: Path, *, size: str = "small", seed: int = 0, workers: int | None = None,
        max_keypoints: int = 1000, points_per_image: int = 40, epochs: float = 4.0,
        progress: bool = True) -> dict:
    """Train both variants and write ``predict.json``, ``predict.md``, ``predict.png``.

    Raises:
      ValueError: fewer than two training scenes (``tiny`` has one: use ``small``).
    """
    from rp_jax.conditional import inputs
    from rp_jax.conditional import model as cmodel
    from rp_jax.conditional import train as ctrain
    from rp_jax.datasets import registry

    workdir = Path(workdir)
    root = generate(PRESET, workdir / "layouts" / PRESET, size=size, seed=seed,
                    workers=workers, progress=progress)
    dataset = registry.get("webcam_clipart")
    captures = dataset.read(root)
    train_scenes = sorted(dataset.splits("synthetic", [str(c.viewpoint) for c in captures])
                          .get("train", []))
    if len(train_scenes) < 2:
        raise ValueError(f"{PRESET} {size}: {len(train_scenes)} training scene(s); holding "
                         "one out needs two (use --size small)")
    labelled = {str(x[0]["viewpoint"][0]): x for x in viewpoint_outcomes(
        root, workdir / "cache" / PRESET, max_keypoints=max_keypoints, progress=progress,
        viewpoints=train_scenes)}
    settings = ctrain.FitSettings(num_epochs=epochs, seed=seed)
    result = {"preset": PRESET, "size": size, "seed": seed, "epochs": epochs,
              "points_per_image": points_per_image, "train_scenes": train_scenes,
              "folds": {}, "variants": {}}
    pooled = {name: [] for name in VARIANTS}
    for held_scene in train_scenes:  # each training scene held out in turn
        train_arrays, _ = pair_arrays([labelled[s] for s in train_scenes if s != held_scene],
                                      captures, points_per_image=points_per_image, seed=seed)
        held_arrays, held_years = pair_arrays([labelled[held_scene]], captures,
                                              points_per_image=points_per_image, seed=seed)
        outcome = held_arrays.points["outcome"]
        known = outcome >= 0
        fold = {"train_points": len(train_arrays), "held_out_points": len(held_arrays)}
        for name, scales in VARIANTS.items():
            scales = inputs.DECAY_TIME_SCALES_YEARS if scales is None else scales
            net = cmodel.ConditionalPredictor(decay_time_scales=tuple(scales))
            params, history = ctrain.fit(net, train_arrays, settings, progress=progress)
            probability = ctrain.predict_probabilities(net, params, held_arrays)
            fold[name] = {"train_bce": history[-1]["train_bce"],
                          "bins": bin_table(probability, outcome, held_years)}
            pooled[name].append((probability[known], outcome[known], held_years[known]))
            log.info("held out %s, %s: BCE %.4f", held_scene, name,
                     fold[name]["bins"][-1]["bce"])
        result["folds"][held_scene] = fold
    for name, scales in VARIANTS.items():
        p, o, y = (np.concatenate(a) for a in zip(*pooled[name]))
        result["variants"][name] = {
            "decay_time_scales": list(inputs.DECAY_TIME_SCALES_YEARS if scales is None
                                      else scales),
            "bins": bin_table(p, o, y)}
    files.write_json(workdir / "predict.json", result)
    files.write_text(workdir / "predict.md", markdown(result))
    plot(result, workdir / "predict.png")
    return result
