"""dmmr-bench: walkthrough benchmarks after Section 4 of the paper (see docs/benchmarks.md)."""
