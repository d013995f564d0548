"""``python -m experiments.map_summarization``: map summarization with RP (Sec. V, Fig. 11)."""
