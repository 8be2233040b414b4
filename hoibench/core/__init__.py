"""Core utilities every stage uses: ids, guarded I/O, errors, interrupts, executors, geometry, the skeleton and plausibility bounds."""
