"""Global image descriptors for retrieval: VLAD over RootSIFT (Sec. V-B of the paper).

The paper represents every image by NetVLAD (Arandjelovic et al., CVPR 2016). NetVLAD
weights cannot be downloaded here, so the default global descriptor is classic VLAD
(Jegou et al., CVPR 2010) with the improvements NetVLAD itself builds on (Arandjelovic &
Zisserman, "All about VLAD", CVPR 2013): RootSIFT local descriptors, a k-means vocabulary
learned on the database images, intra-normalisation (per-cluster L2), signed power
normalisation (alpha = 0.5) and a final L2 normalisation. Any other global descriptor
(NetVLAD, ...) can be supplied from a file instead (``rp_jax.localize.retrieval``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["kmeans_pp", "learn_vocabulary", "rootsift", "vlad"]


def rootsift(descriptors: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """RootSIFT (Arandjelovic & Zisserman 2012): L1-normalise, then element-wise sqrt.

    Args:
      descriptors: [N, D] non-negative SIFT descriptors (uint8 or float).
      eps: guard against empty descriptors.

    Returns:
      [N, D] float32 descriptors with unit L2 norm.
    """
    d = np.asarray(descriptors, dtype=np.float32)
    if d.ndim != 2:
        raise ValueError(f"descriptors must be [N, D], got shape {d.shape}")
    d = np.maximum(d, 0.0)
    d = d / (d.sum(axis=1, keepdims=True) + eps)
    return np.sqrt(d)


def learn_vocabulary(
    descriptors: np.ndarray, num_words: int = 64, seed: int = 0, max_samples: int = 200_000
) -> np.ndarray:
    """k-means vocabulary (visual words) of local descriptors.

    Args:
      descriptors: [N, D] local descriptors from the database images (already RootSIFT if
        VLAD will be computed on RootSIFT).
      num_words: vocabulary size k (capped at N).
      seed: seed of the sampling and of the k-means++ initialisation.
      max_samples: fit on at most this many descriptors (random subsample).

    Returns:
      [k, D] float32 cluster centres.
    """
    d = np.asarray(descriptors, dtype=np.float32)
    if d.ndim != 2 or len(d) == 0:
        raise ValueError(f"need a non-empty [N, D] descriptor array, got shape {d.shape}")
    rng = np.random.default_rng(seed)
    if len(d) > max_samples:
        d = d[rng.choice(len(d), max_samples, replace=False)]
    k = int(min(num_words, len(d)))
    from scipy.cluster.vq import kmeans2  # here: rp_jax.localize imports this module eagerly

    data = d.astype(np.float64)
    centres, _ = kmeans2(data, kmeans_pp(data, k, rng), minit="matrix")
    return centres.astype(np.float32)


def kmeans_pp(data: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding (Arthur & Vassilvitskii, SODA 2007): the first centre uniformly,
    each next one with probability proportional to the squared distance to its nearest
    centre so far.

    The same draws and the same centres as SciPy's ``kmeans2(..., minit="++")`` given the
    same ``rng`` (a test checks it), in k passes over the data instead of about k²/2:
    SciPy measures every point against all i centres chosen so far at each step i (about
    two thousand passes for a 64-word vocabulary); here each point's nearest squared
    distance is kept and only the new centre measured.

    Args:
      data: [N, D] float64 points.
      k: number of centres, 1 <= k <= N.
      rng: the generator; consumed as SciPy consumes it (one integer, then one uniform
        per further centre).

    Returns:
      [k, D] float64 initial centres.
    """
    from scipy.spatial.distance import cdist

    init = np.empty((k, data.shape[1]), np.float64)
    init[0] = data[rng.integers(data.shape[0])]
    nearest = cdist(init[:1], data, metric="sqeuclidean")[0]
    for i in range(1, k):
        cumprobs = (nearest / nearest.sum()).cumsum()
        init[i] = data[int(np.searchsorted(cumprobs, rng.uniform()))]
        if i + 1 < k:
            np.minimum(nearest, cdist(init[i:i + 1], data, metric="sqeuclidean")[0],
                       out=nearest)
    return init


def vlad(descriptors: np.ndarray, vocabulary: np.ndarray, alpha: float = 0.5) -> np.ndarray:
    """VLAD of one image's local descriptors.

    Args:
      descriptors: [N, D] local descriptors of the image (N may be 0).
      vocabulary: [k, D] cluster centres.
      alpha: power-normalisation exponent (0.5: signed square root).

    Returns:
      [k * D] float32 descriptor with unit L2 norm (all zeros if the image has none).
    """
    centres = np.asarray(vocabulary, dtype=np.float32)
    k, dim = centres.shape
    d = np.asarray(descriptors, dtype=np.float32).reshape(-1, dim)
    v = np.zeros((k, dim), dtype=np.float64)
    if len(d):
        from scipy.spatial import cKDTree

        _, word = cKDTree(centres).query(d)
        np.add.at(v, word, d - centres[word])
    # Intra-normalisation: each cluster's residual sum to unit norm (bursts count once).
    norms = np.linalg.norm(v, axis=1, keepdims=True)
    v = np.divide(v, norms, out=np.zeros_like(v), where=norms > 0)
    v = np.sign(v) * np.abs(v) ** alpha
    v = v.reshape(-1)
    n = np.linalg.norm(v)
    return (v / n if n > 0 else v).astype(np.float32)
