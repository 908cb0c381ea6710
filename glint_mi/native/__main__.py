"""``python -m glint_mi.native``: build the k-buffer traversal library (make runs it; a missing compiler is not an
error: the integrator then uses Mitsuba's BVH queries)."""
import sys

from . import build

if __name__ == "__main__":
    try:
        build(verbose=True)
    except RuntimeError as exc:
        print(f"glint_mi.native: not built ({exc}); the integrator will use Mitsuba's BVH queries (slower)")
    sys.exit(0)
