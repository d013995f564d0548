"""Beyond the paper (issue 17): a repeatability predictor conditioned on the target.

The paper's predictor (``rp_jax.model``) maps a patch, its position and its capture time to
a T-vector: the expected share of each timestamp's images that re-detect the point. Its
discussion (Sec. V) names what it cannot see: the sun direction, the weather, the
semantics. This package predicts the outcome of one image pair instead,

    score(patch, xy, capture time [+ conditions], target time [+ conditions]) -> logit

trained on the per-pair outcomes the ground truth averages into y^j
(``rp_jax.datasets.outcomes``) with a binary cross-entropy on the known pairs. Any target
time is a query (a continuous time encoding, no slots), and the paper's T-vector is the
mean probability over a timestamp's targets (``model.t_vector``), so the two predictors are
scored on the same labels. Conditions are each optional (``inputs.CONDITIONS``): ``sun``,
``weather``, ``semantics``, ``appearance`` (a global descriptor of the image itself,
``appearance``).

Modules: ``inputs`` (pure encodings of time and conditions), ``model`` (the Flax module,
the loss, the T-vector, an opt-in long-term decay basis over the years between capture
and target), ``sun_task`` (a learnable task whose answer depends on the sun), ``decay_task``
(one whose answer decays over the years at a rate set by the patch),
``pairs`` (records + sidecar -> arrays and batches), ``train`` (the fit loop) and
``appearance`` (the descriptor).
"""
