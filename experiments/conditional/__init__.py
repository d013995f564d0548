"""Beyond the paper (issue 17): the conditional predictor against the paper's, by
cross-validation on the training viewpoints (``python -m experiments.conditional``)."""
