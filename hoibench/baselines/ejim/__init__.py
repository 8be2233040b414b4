"""EJIM baseline: ``config`` (paper, tiny), ``mamba`` (pure-PyTorch Mamba block), ``model``
(dual-branch HOI Mamba, condition injector, dynamic interaction blocks with progressive
masking), ``spec`` (model and losses for the shared trainer and sampler)."""
