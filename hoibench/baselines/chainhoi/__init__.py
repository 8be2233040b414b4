"""ChainHOI baseline: ``config`` (paper, tiny), ``graph`` (joint graph, kinetic chains),
``model`` (GST-GCN + KIM denoiser), ``data`` (store -> training items), ``train`` and
``sample`` (run folder -> standard submission)."""
