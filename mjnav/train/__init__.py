"""PPO training on the navigation environments with rsl-rl (the only torch users besides the adapter).

``config`` (TrainConfig), ``model`` (per-layer-activation MLP), ``runner`` (OnPolicyRunner
construction, progress, checkpoints), ``curriculum``, ``evaluate``, ``export``, ``distributed``
(data-parallel PPO under torchrun), ``session`` (what ``scripts/train.py`` runs).
"""
