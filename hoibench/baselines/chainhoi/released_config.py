"""ChainHOI ``released`` configuration: the network and recipe of the public ChainHOI code
(``Huanggh531/ChainHOI``, commit 4990160, ``scripts/train_behave.sh`` with
``configs/model/chainhoi_behave.yaml`` and ``configs/model/gcn_denoiser/chainhoi.yaml``).

=================  ========  =============================================================
field              released  meaning
=================  ========  =============================================================
blocks             6         N blocks (input transform + ST-GCN + semantic module + KIM)
base_dim           64        width of the first block; doubles at ``up_blocks``
up_blocks          (2, 4)    1-based blocks whose width doubles: 64 -> 128 -> 256
model_dim          64        width of the KIM decoders (chain tokens, node tokens)
heads              4         attention heads of every decoder
decoder_layers     4         layers of each text / object context decoder (KIM and semantic)
gn_groups          4         GroupNorm groups of the input and graph-convolution norms
                             (times width / base_dim inside the graph convolution)
cond_dim           512       width of the text and object tokens and the time token
time_dim           256       sinusoidal timestep width
object_points      512       mesh vertices given to PointNet++ (MSG), 16 object tokens out
text_encoder       minilm    token states projected to ``cond_dim`` (the public code: CLIP)
mask               released  Kinematic-aware Decoder mask: "released" (additive 1 - mask)
                             or "paper" (boolean)
padding            masked    "masked": GroupNorm statistics over valid frames and zeroed
                             padded frames before the temporal convolutions (no leak in
                             time); "reference": the public code's arithmetic exactly
=================  ========  =============================================================

Recipe: AdamW lr 1e-4, weight decay 0, no gradient clipping, no EMA, batch 16, windows of at
most 196 rows; diffusion T = 1000, linear betas, x0 prediction, DDIM 50, guidance 2, text
dropped with probability 0.2; ``L = L_diff + 2 L_h + 1 L_o`` (:mod:`.released_losses`).
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import RunConfig, TrainConfig, check_ints
from ..config import TEXT_ENCODERS

PADDING_MODES = ("masked", "reference")
MASK_MODES = ("paper", "released")


@dataclass(frozen=True)
class ReleasedConfig:
    blocks: int = 6
    base_dim: int = 64
    up_blocks: tuple[int, ...] = (2, 4)
    model_dim: int = 64
    heads: int = 4
    decoder_layers: int = 4
    gn_groups: int = 4
    cond_dim: int = 512
    time_dim: int = 256
    dropout: float = 0.1
    object_points: int = 512
    object_tokens: int = 16
    object_source: str = "vertices"   # PointNet++ input: mesh vertices (the public code's object_sample)
    text_encoder: str = "minilm"
    text_max_tokens: int = 32
    text_layers: int = 1
    mask: str = "released"
    padding: str = "masked"
    variant: str = "released"          # marks this config family in run cards

    def __post_init__(self) -> None:
        check_ints(self, ("blocks", "base_dim", "model_dim", "heads", "decoder_layers", "gn_groups", "cond_dim",
                          "time_dim", "object_points", "object_tokens", "text_max_tokens", "text_layers"), "model",
                   hi=100_000)
        if self.variant != "released":
            raise ValueError(f"model.variant: expected 'released', got {self.variant!r}")
        if self.mask not in MASK_MODES:
            raise ValueError(f"model.mask: expected one of {MASK_MODES}, got {self.mask!r}")
        if self.padding not in PADDING_MODES:
            raise ValueError(f"model.padding: expected one of {PADDING_MODES}, got {self.padding!r}")
        if self.text_encoder not in TEXT_ENCODERS:
            raise ValueError(f"model.text_encoder: expected one of {TEXT_ENCODERS}, got {self.text_encoder!r}")
        if self.object_source not in ("vertices", "surface"):
            raise ValueError(f"model.object_source: expected 'vertices' or 'surface', got {self.object_source!r}")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"model.dropout: expected [0, 1), got {self.dropout!r}")
        if any(not isinstance(b, int) or not 1 <= b <= self.blocks for b in self.up_blocks):
            raise ValueError(f"model.up_blocks: expected block numbers in [1, {self.blocks}], got {self.up_blocks!r}")
        width = self.base_dim * 2 ** len(self.up_blocks)
        for name, w in (("base_dim", self.base_dim), ("model_dim", self.model_dim), ("cond_dim", self.cond_dim)):
            if w % self.heads:
                raise ValueError(f"model.{name} ({w}) must be divisible by model.heads ({self.heads})")
        if self.base_dim % self.gn_groups or width < 6:
            raise ValueError(f"model.base_dim ({self.base_dim}) must be divisible by model.gn_groups "
                             f"({self.gn_groups}) and the last width >= 6")
        if self.object_tokens != 16 or self.object_points < 16:
            raise ValueError(f"model.object_tokens: PointNet++ (MSG) gives 16 object tokens from >= 16 points, got "
                             f"object_tokens {self.object_tokens}, object_points {self.object_points}")
        if self.time_dim % 2:
            raise ValueError(f"model.time_dim: expected an even integer, got {self.time_dim}")


def released_preset() -> RunConfig:
    """The public code's BEHAVE network and recipe (batch 16, no EMA, no clipping, no weight decay)."""
    return RunConfig(name="released", model=ReleasedConfig(),
                     train=TrainConfig(steps=50_000, batch_size=16, lr=1e-4, weight_decay=0.0, max_frames=196,
                                       ema_decay=0.0, grad_clip=0.0, lambda_contact=2.0, lambda_object=1.0))
