"""Submission format: write, read safely, validate; ground-truth submissions from a store.

A submission is a directory, or a ``.zip`` of one (read in place, never extracted)::

    submission.json            {"method", "version", "url", "representation", "fps",
                                "flags": {"uses_gt_length", "samples_per_prompt",
                                          "checkpoint_selection"}}
    samples/<test_id>.npz      joints    (K, T, 22, 3) float32, metres, y-up (docs/protocol.md)
                               obj_rot   (K, T, 3, 3)  or  obj_rotvec (K, T, 3)   (one of them)
                               obj_trans (K, T, 3)     object pose v = R v_template + t
                               hml263    (K, T-1 or T, 263)  optional
                               markers   (K, T, 77, 3) float, metres, the joints' frame:
                                         InterAct's body-surface markers
                                         (:mod:`hoibench.bodies.markers`); optional, required
                                         by tracks whose evaluator reads them (``interact``:
                                         the track's ``submission_arrays``)

The object arrays are required for test clips that have an object; a human-only store's
clips (RICH: static scenes) need ``joints`` only (object arrays there draw a warning).

K samples per prompt (1 is enough for every metric but MultiModality, which needs the
protocol's 30), T frames at the submission's ``fps`` (must equal the store's).

Safety (nothing here unpickles or trusts sizes): ``.npz`` files are read with
``allow_pickle=False`` after every member's ``.npy`` header has been parsed without loading
data (:func:`npz_headers`): an object array (pickled Python objects) is rejected with a
message, and so is a header whose claimed shape needs more than ``max_array_bytes`` (2 GiB by
default) or more bytes than the member holds. Zip members with absolute paths, ``..``
components, backslashes, drive letters or symlinks are rejected and never read.

:func:`validate` reports *every* problem at once as :class:`Problem` ``(id, field, message)``:
missing or extra ids against the store's test split, shapes, dtypes, non-finite values,
implausible units (e.g. centimetres: a body taller than 3 m), lengths out of range, object
rotations that are not rotations, ``submission.json`` fields. A broken or partial submission
never raises and is never scored as complete (:class:`ValidationReport` ``complete``).

The code lives in four parts; this module re-exports them (import from here):

* :mod:`~hoibench.scoring.submission_read` -- file names, byte budgets, safe ``.npz``
  parsing and the guarded reader :class:`Submission`;
* :mod:`~hoibench.scoring.validate` -- :func:`validation_report`, :func:`validate`, the
  ``submission.json`` / ids / shapes checks and ``hoibench validate``;
* :mod:`~hoibench.scoring.validate_arrays` -- value checks of one file's arrays
  (:func:`check_arrays`, :func:`encode_sample`);
* :mod:`~hoibench.scoring.submission_write` -- :func:`write_submission`, :func:`from_store`
  and ``hoibench submission from-store``.
"""
from __future__ import annotations

from .submission_read import (BYTES_PER_VALUE, DEFAULT_MAX_SAMPLES_PER_PROMPT, FILE_OVERHEAD_BYTES, ID_PATTERN,
                              KNOWN_ARRAYS, MAX_ARRAY_BYTES, MAX_EXTRA_ARRAYS, MAX_JSON_BYTES, MAX_ZIP_DIRECTORY_BYTES,
                              SAMPLES_DIR, SUBMISSION_JSON, VALUES_PER_FRAME, ArrayHeader, Problem, Submission,
                              SubmissionError, SubmissionLimits, limits_for, load_npz, max_frames, npz_headers,
                              zip_directory_size)
from .submission_write import check_output_free, from_store, main_submission_from_store, write_submission
from .validate import (FLAG_FIELDS, REQUIRED_FIELDS, UP_AXIS_MIN_CLIPS, ValidationReport,
                       main_validate, submission_context, validate, validation_report)
from .validate_arrays import (ACCEPTED_DTYPES, BODY_HEIGHT_RANGE_M, MAX_ABS_COORD_M, MAX_FEATURE_ABS, MAX_OBJECT_DISTANCE_FRAME_M,
                              MAX_OBJECT_DISTANCE_M, MAX_ROTVEC_RAD, MAX_SPEED_MPS, MEAN_BODY_HEIGHT_M, ClipContext,
                              check_arrays, encode_sample)

__all__ = ["Problem", "SubmissionError", "ArrayHeader", "Submission", "ValidationReport", "npz_headers", "load_npz",
           "validate", "validation_report", "write_submission", "from_store", "main_validate",
           "main_submission_from_store", "SUBMISSION_JSON", "SAMPLES_DIR", "MAX_ARRAY_BYTES"]
