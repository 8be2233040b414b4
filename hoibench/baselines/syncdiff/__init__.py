"""SyncDiff baseline (multi-body interactions): ``config`` (paper, tiny, ablation switches),
``frequency`` (low/high split), ``bps`` (basis point set), ``geometry`` (rel/comb in torch),
``sync`` (alignment loss, explicit synchronization), ``data`` (training set), ``model``
(transformer denoiser), ``trainer``, ``sampler``."""
