"""CATMO configurations: ``paper`` (published and T2M-GPT sizes) and ``tiny`` (CPU minutes).

=====================  ==========  =======  ===================================================
field                  paper       tiny     meaning
=====================  ==========  =======  ===================================================
vq.width               512         64       channels of the Conv1D encoder/decoder
vq.code_dim            512         64       codebook vector size
vq.motion_codes        512         128      motion codebook size (CATMO sec. 1.1)
vq.contact_codes       512         64       contact codebook size (CATMO Table 4: smaller is better)
vq.down_t              2           2        stride-2 stages: downsampling l = 2^down_t = 4
vq.depth               3           2        residual blocks per stage (dilations 3^k)
text.width             512         64       interaction-aware text / movement embedding size
gpt.width              1024        128      transformer width (T2M-GPT)
gpt.layers             18          3        causal transformer layers (T2M-GPT: 9 + 9)
gpt.heads              16          4
gpt.corrupt_rate       0.5         0.3      fraction of input indices replaced at random
train.vq_steps         300000      4000     motion VQ-VAE iterations (CATMO supp. 2.1)
train.contact_steps    300000      1500     contact VQ-VAE iterations
train.gpt_steps        100000      3000     intertwined GPT iterations
train.batch_size       16          32       (CATMO supp. 2.1: 16 for every stage)
train.lr               2e-4        1e-3     AdamW
=====================  ==========  =======  ===================================================

Not given by the paper, and hoibench's choices (docs/baselines.md): the movement encoder's
and text encoder's sizes and steps, the alignment-loss weight and its differentiable path
(expected codebook vectors under the predicted distribution), the velocity term's weight
(0.5, T2M-GPT's), the commitment weight beta (0.02, T2M-GPT's) and the object head.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..config import (TEXT_ENCODERS, TrainLoopConfig, check_architecture, check_choice, check_divisible, check_interval,
                      check_ints, check_nonnegative, check_object_sampling, dotted_replace, sections_from_dict,
                      sections_to_dict)

CORRUPTION_MODES = ("token", "unit")
SECTIONS = ("vq", "text", "gpt", "object", "train")


@dataclass(frozen=True)
class VQConfig:
    """Both VQ-VAEs (motion over hml263, contacts over the 22 joints' labels)."""
    width: int = 512
    code_dim: int = 512
    motion_codes: int = 512
    contact_codes: int = 512
    down_t: int = 2
    depth: int = 3
    dilation_growth: int = 3
    ema_mu: float = 0.99             # codebook EMA decay
    beta: float = 0.02               # commitment weight (L_c)
    lambda_velocity: float = 0.5     # smooth-L1 on the joint-position channels' frame differences
    window: int = 64                 # training window (rows)

    def __post_init__(self) -> None:
        check_ints(self, ("width", "code_dim", "motion_codes", "contact_codes", "depth", "dilation_growth", "window"),
                       "vq", hi=100_000)
        check_ints(self, ("down_t",), "vq", lo=0, hi=6)
        if self.motion_codes < 2 or self.contact_codes < 2:
            raise ValueError("vq.motion_codes and vq.contact_codes: expected at least 2 codes")
        check_interval(self, ("ema_mu",), "vq", "(0, 1)")
        check_nonnegative(self, ("beta", "lambda_velocity"), "vq")
        if self.window % (2 ** self.down_t):
            raise ValueError(f"vq.window ({self.window}) must be a multiple of 2^vq.down_t ({2 ** self.down_t})")

    @property
    def unit(self) -> int:
        """Frames (hml263 rows) per token: l = 2^down_t."""
        return 2 ** self.down_t


@dataclass(frozen=True)
class TextMatchConfig:
    """Interaction-aware text encoder and movement encoder (CATMO sec. 4.3, supp. 1.2)."""
    encoder: str = "minilm"          # text input: frozen sentence-encoder states, or trainable word tokens
    max_tokens: int = 32
    width: int = 512                 # embedding size of both encoders
    hidden: int = 512
    margin: float = 10.0             # negative-pair margin m (supp. eq. 3)
    movement_ae_steps: int = 20000   # part 1 of the movement encoder: reconstruction
    match_steps: int = 20000         # text encoder + part 2: contrastive

    def __post_init__(self) -> None:
        check_ints(self, ("max_tokens", "width", "hidden"), "text", hi=100_000)
        check_ints(self, ("movement_ae_steps", "match_steps"), "text", lo=0)
        check_choice(self, "encoder", "text", TEXT_ENCODERS)
        if not self.margin > 0:
            raise ValueError(f"text.margin: expected > 0, got {self.margin!r}")


@dataclass(frozen=True)
class GPTConfig:
    width: int = 1024
    layers: int = 18
    heads: int = 16
    ff_mult: int = 4
    dropout: float = 0.1
    max_units: int = 50              # longest motion in tokens (50 x 4 = 200 rows)
    corrupt_rate: float = 0.5
    corruption: str = "token"        # "token": every index on its own (CATMO); "unit": m_i and c_i together
    lambda_align: float = 0.1        # text-motion alignment loss weight
    object_points: int = 1024        # HOI tracks: object surface samples (CATMO supp.: 1024)
    object_tokens: int = 32
    object_knn: int = 32
    temperature: float = 1.0         # sampling

    def __post_init__(self) -> None:
        check_ints(self, ("width", "layers", "heads", "ff_mult", "max_units", "object_points", "object_tokens",
                          "object_knn"), "gpt", hi=100_000)
        check_divisible(self, "width", "heads", "gpt")
        check_interval(self, ("dropout", "corrupt_rate"), "gpt", "[0, 1)")
        check_choice(self, "corruption", "gpt", CORRUPTION_MODES)
        check_nonnegative(self, ("lambda_align",), "gpt")
        check_interval(self, ("temperature",), "gpt", "(0, 100]")
        check_object_sampling(self, "gpt")


@dataclass(frozen=True)
class ObjectHeadConfig:
    """hoibench's extension for the HOI tracks (not in the paper): object trajectory from the
    decoded motion, the decoded contacts and the object's geometry."""
    width: int = 256
    layers: int = 4
    steps: int = 20000

    def __post_init__(self) -> None:
        check_ints(self, ("width", "layers"), "object", hi=100_000)
        check_ints(self, ("steps",), "object", lo=0)


@dataclass(frozen=True)
class CatmoTrainConfig(TrainLoopConfig):
    vq_steps: int = 300_000
    contact_steps: int = 300_000
    gpt_steps: int = 100_000
    batch_size: int = 16
    lr: float = 2e-4
    weight_decay: float = 0.0
    log_every: int = 100

    def __post_init__(self) -> None:
        check_ints(self, ("vq_steps", "contact_steps", "gpt_steps"), "train", lo=0)
        check_ints(self, ("batch_size", "min_frames", "checkpoint_every", "log_every"), "train")
        check_interval(self, ("lr",), "train", "(0, 1)")
        check_interval(self, ("weight_decay",), "train", "[0, 1)")


@dataclass(frozen=True)
class CatmoConfig:
    name: str
    vq: VQConfig = field(default_factory=VQConfig)
    text: TextMatchConfig = field(default_factory=TextMatchConfig)
    gpt: GPTConfig = field(default_factory=GPTConfig)
    object: ObjectHeadConfig = field(default_factory=ObjectHeadConfig)
    train: CatmoTrainConfig = field(default_factory=CatmoTrainConfig)

    def __post_init__(self) -> None:
        for s in SECTIONS:
            check_architecture(getattr(self, s), s)

    def to_dict(self) -> dict:
        return sections_to_dict(self, SECTIONS)

    @classmethod
    def from_dict(cls, d: dict, where: str = "config") -> "CatmoConfig":
        kinds = {"vq": VQConfig, "text": TextMatchConfig, "gpt": GPTConfig, "object": ObjectHeadConfig,
                 "train": CatmoTrainConfig}
        return cls(**sections_from_dict(d, kinds, where))

    def replace(self, **changes) -> "CatmoConfig":
        """A copy with dotted overrides, e.g. ``replace(**{"train.gpt_steps": 10})``."""
        return CatmoConfig.from_dict(dotted_replace(self.to_dict(), SECTIONS, changes))

    @property
    def total_steps(self) -> int:
        t = self.train
        return t.vq_steps + t.contact_steps + self.text.movement_ae_steps + self.text.match_steps + t.gpt_steps \
            + self.object.steps


def preset(name: str = "tiny") -> CatmoConfig:
    """``paper`` (CATMO supp. 2.1 and T2M-GPT sizes) or ``tiny`` (trains on the synthetic
    track on 2 CPU cores in minutes)."""
    if name == "paper":
        return CatmoConfig(name="paper")
    if name == "tiny":
        return CatmoConfig(
            name="tiny",
            vq=VQConfig(width=64, code_dim=64, motion_codes=128, contact_codes=64, depth=2),
            text=TextMatchConfig(encoder="tokens", width=64, hidden=128, movement_ae_steps=600, match_steps=1500),
            gpt=GPTConfig(width=128, layers=3, heads=4, ff_mult=2, dropout=0.0, corrupt_rate=0.3, object_points=256,
                          object_tokens=16, object_knn=16),
            object=ObjectHeadConfig(width=64, layers=3, steps=1500),
            train=CatmoTrainConfig(vq_steps=4000, contact_steps=1500, gpt_steps=3000, batch_size=32, lr=1e-3,
                                   checkpoint_every=250, log_every=50))
    raise ValueError(f"unknown CATMO config {name!r}; choose 'paper' or 'tiny'")
