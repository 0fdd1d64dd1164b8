"""The learned simulator: one learned step, its physics guards, its wall inputs and the rollout."""
