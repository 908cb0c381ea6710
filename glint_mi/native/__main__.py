"""``python -m glint_mi.native``: build the k-buffer traversal library (make runs it; a missing compiler is not an
error: the integrator then uses Mitsuba's BVH queries)."""
import argparse
import sys

from glint_mi.native import build

if __name__ == "__main__":
    ap = argparse.ArgumentParser(prog="python -m glint_mi.native", description=__doc__.split("\n")[0] + ")",
                                 epilog="The library is built with the system C++ compiler against the Embree headers "
                                        "and library inside the mitsuba wheel and the thread pool of the drjit wheel; "
                                        "it is rebuilt when the sources are newer or it no longer loads.")
    ap.parse_args()
    try:
        build(verbose=True)
    except RuntimeError as exc:
        print(f"glint_mi.native: not built ({exc}); the integrator will use Mitsuba's BVH queries (slower)")
    sys.exit(0)
