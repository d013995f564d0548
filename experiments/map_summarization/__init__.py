"""``python -m experiments.map_summarization``: map summarization with RP (Sec. V, IV-B, Fig. 11)."""
