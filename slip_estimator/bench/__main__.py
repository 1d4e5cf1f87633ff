"""``python -m slip_estimator.bench``: the same as ``slip-estimator bench`` (and the workers'
entry point)."""
import sys

from slip_estimator.bench.cli import bench_main

sys.exit(bench_main())
