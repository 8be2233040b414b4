"""Multi-body interaction (N hands or humans with M rigid objects): metrics and helpers.

* :mod:`~hoibench.multibody.metrics` -- SyncDiff's CSR, CRR, CSIoU, IV, ID and DiffH2O's
  wrist-trajectory diversities SD and OD (docs/multibody_metrics.md).
"""
