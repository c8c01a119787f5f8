"""Evaluation on held-out synthetic scenes: the paper's Table 1 and S's speed/accuracy trade."""
