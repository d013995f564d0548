"""Time and peak memory of ``python -m rp_jax.keypoints`` on a large photo, with and without
``--max-size`` (the figures behind its ``--help``; a benchmark that prints, not a timed test).

    python -m experiments.benchmark.large_image [--width 4000] [--height 3000]
        [--max-size 0 640 ...] [--predictor webcam_clipart-synthetic] [--out DIR]

Writes a textured JPEG of ``--width`` x ``--height`` into ``--out`` (a temporary folder by
default), then runs the command once per ``--max-size`` value, each in its own process so
that each peak resident memory (``ru_maxrss`` of that child) is its own, and prints one row
per value: the size detected at, keypoints, wall seconds and peak memory. ``0`` keeps the
photo as it is: the photo of issue 27 (8892x6000) then took 90 s and 12.8 GB; a 4000x3000
one 14 s and 2.8 GB. With the default limit (the model's training resolution) the detection
and prediction cost what a 640-pixel image does; the decoded photo itself (3 bytes a pixel,
twice at the peak) is what remains of its size.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_CHILD = """
import json, resource, sys, time
from rp_jax.keypoints import __main__ as command
t0 = time.perf_counter()
rc = command.main(sys.argv[1:])
wall = time.perf_counter() - t0
peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print("RESULT " + json.dumps({"rc": rc, "wall_s": wall, "peak_mb": peak_mb}))
"""


def write_photo(path: Path, width: int, height: int, seed: int = 0) -> Path:
    """A JPEG with structure at every scale (blurred noise, upsampled), SIFT finds plenty."""
    import cv2

    rng = np.random.default_rng(seed)
    base = rng.normal(size=(height // 8 + 1, width // 8 + 1, 3)).astype(np.float32)
    img = cv2.resize(cv2.GaussianBlur(base, (0, 0), 2.0), (width, height),
                     interpolation=cv2.INTER_CUBIC)
    img += 0.3 * rng.normal(size=img.shape).astype(np.float32)
    img = np.clip((img - img.mean()) / img.std() * 45 + 128, 0, 255).astype(np.uint8)
    cv2.imwrite(str(path), img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    return path


def measure(photo: Path, out: Path, max_size: int, predictor: str) -> dict:
    """One run of the command in a child process: its exit status, wall time, peak memory."""
    argv = [str(photo), "--predictor", predictor, "--captured", "2024-06-01 09:30",
            "--out", str(out / f"max_{max_size}"), "--max-size", str(max_size), "--no-overlay",
            "--overwrite"]
    proc = subprocess.run([sys.executable, "-c", _CHILD, *argv], capture_output=True,
                          text=True, check=False)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    if not lines:
        raise RuntimeError(f"the run with --max-size {max_size} failed:\n{proc.stderr[-2000:]}")
    result = json.loads(lines[-1][len("RESULT "):])
    with np.load(out / f"max_{max_size}" / f"{photo.stem}.npz") as z:
        result.update(keypoints=int(len(z["xy"])), detection_size=z["detection_size"].tolist())
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.benchmark.large_image",
                                description=__doc__.split("\n")[0])
    p.add_argument("--width", type=int, default=4000, help="photo width (default 4000)")
    p.add_argument("--height", type=int, default=3000, help="photo height (default 3000)")
    p.add_argument("--max-size", type=int, nargs="+", default=[640, 0], metavar="PX",
                   help="--max-size values to run (default 640 0; 0: no limit)")
    p.add_argument("--predictor", default="webcam_clipart-synthetic",
                   help="the model (default webcam_clipart-synthetic)")
    p.add_argument("--out", type=Path, help="folder for the photo and outputs (default: temp)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        photo = write_photo(out / f"photo_{args.width}x{args.height}.jpg", args.width,
                            args.height)
        print(f"photo {photo.name}: {args.width}x{args.height} "
              f"({args.width * args.height / 1e6:.1f} MP, {photo.stat().st_size / 1e6:.1f} MB "
              f"JPEG, written in {time.perf_counter() - t0:.1f} s)")
        print(f"{'--max-size':>10} {'detected at':>12} {'keypoints':>9} {'wall s':>7} "
              f"{'peak MB':>8}")
        for m in args.max_size:
            r = measure(photo, out, m, args.predictor)
            size = "x".join(str(v) for v in r["detection_size"])
            print(f"{m:>10} {size:>12} {r['keypoints']:>9} {r['wall_s']:>7.1f} "
                  f"{r['peak_mb']:>8.0f}", flush=True)
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"(this driver's own peak: {own:.0f} MB; each row is its child's)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
