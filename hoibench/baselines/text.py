"""Text conditions of the diffusion baselines: captions -> token inputs for the model."""
from __future__ import annotations

import torch

from . import joint_data as D


class TextConditioner:
    """Captions -> (text input, pad) for a baseline model's ``encode_text``: word ids for the
    ``tokens`` encoder; frozen sentence-encoder token states for ``minilm`` (cached)."""

    def __init__(self, encoder: str, max_tokens: int, vocab: list[str] | None = None):
        self.encoder, self.max_tokens, self.vocab = encoder, max_tokens, vocab
        self._tok = self._net = None
        self.width = 0
        self.weights_sha256 = ""
        if encoder == "minilm":
            from ..evaluator.text import load_pretrained, packaged_minilm_path, weights_sha256
            folder = packaged_minilm_path()
            self._tok, self._net = load_pretrained(folder)
            self._net.eval()
            self.width = int(self._net.config.hidden_size)
            self.weights_sha256 = weights_sha256(folder)

    def describe(self) -> dict:
        if self.encoder == "tokens":
            return {"encoder": "tokens", "vocab": list(self.vocab or [])}
        return {"encoder": "minilm", "width": self.width, "weights_sha256": self.weights_sha256}

    def __call__(self, texts: list[str], device) -> tuple[torch.Tensor, torch.Tensor]:
        if self.encoder == "tokens":
            ids, pad = D.tokenize(texts, self.vocab, self.max_tokens)
            return torch.from_numpy(ids).to(device), torch.from_numpy(pad).to(device)
        with torch.no_grad():
            b = self._tok(list(texts), padding=True, truncation=True, max_length=self.max_tokens, return_tensors="pt")
            states = self._net(**{k: v for k, v in b.items()
                                  if k in ("input_ids", "attention_mask", "token_type_ids")}).last_hidden_state
        return states.float().to(device), (b["attention_mask"] == 0).to(device)
