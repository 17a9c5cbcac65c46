"""Evaluations of the tilt filter against known truth: BROAD trials beside the peer filters,
realistic synthetic recordings, and recordings with one sensor fault each (for σ)."""
