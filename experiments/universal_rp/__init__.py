"""Toward the paper's "universal RP": trained on many synthetic worlds, judged on held-out ones."""
