"""Control-step benchmark (same as ``dqcontrol bench``): prints figures, writes JSON."""

import argparse

from bench import main

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="results/bench.json")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    main(out=args.out, quick=args.quick)
