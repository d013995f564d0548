"""ml_collections configs of the predictor's training (``get_config()`` in each module)."""
