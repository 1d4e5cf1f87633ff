"""``python -m slip_estimator.validation``: the same as ``slip-estimator validate``."""
import sys

from slip_estimator.validation.cli import validate_main

sys.exit(validate_main())
