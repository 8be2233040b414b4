"""Reference baselines trained, sampled and scored by hoibench (docs/baselines.md).

``diffusion``  the diffusion core the diffusion baselines share (schedule, x0, DDIM, CFG, EMA)
``chainhoi``   ChainHOI (CVPR 2025): GST-GCN + KIM over the HOI joint graph
``mean-pose``  text-blind reference generator (mean pose + static object, in :mod:`hoibench.scoring.mean_pose`)
``checkpoint`` baseline run folders: weights, card, id

Training and sampling import only torch, numpy and safetensors.
"""
