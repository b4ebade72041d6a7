"""fit-skin --bones auto on every capture: the count it chooses and what choosing costs (issue 68).

For each capture in ../shared/data (and the built-in walker, humanoid and quadruped, whose true
part counts are 10, 17 and 18) it runs, as a user would, ``skinsynth fit-skin INPUT --bones auto
--json`` and then the same fit with the count it chose given (``--bones K``), and prints one JSON
line: the count, the rule, the rigid-cluster errors around it, both fits' RMSE over the diagonal,
the seconds of each whole command and their ratio (issue 68 asks ≤ 3×).

    python benchmarks/bone_count.py [--only NAME] [--work DIR]
"""

import argparse
import json
import os
import tempfile

from datasets import captures, run


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=None)
    parser.add_argument("--work", default=None, help="folder kept between runs")
    options = parser.parse_args()
    work = options.work or tempfile.mkdtemp(prefix="bone_count_bench_")
    os.makedirs(work, exist_ok=True)
    built = []
    for name in ("walker", "humanoid", "quadruped"):
        if options.only in (None, name):
            path = os.path.join(work, f"{name}.npz")
            run(["example", name, "-o", path, "-q"], work)
            built.append((name, path))
    for name, source in [*captures(work), *built]:
        if options.only and name != options.only:
            continue
        seconds, peak, _, stdout = run(["fit-skin", source, "-o", os.path.join(work, f"{name}.auto.h5"), "--bones",
                                        "auto", "--json", "-q"], work)
        auto = json.loads(stdout)
        count = auto["bone_count"]["chosen"]
        fixed_seconds, _, _, fixed_out = run(["fit-skin", source, "-o", os.path.join(work, f"{name}.fixed.h5"),
                                              "--bones", str(count), "--json", "-q"], work)
        fixed = json.loads(fixed_out)
        print(json.dumps({"capture": name, "bones": count, "rule": auto["bone_count"]["rule"],
                          "rigid_cluster_errors": auto["bone_count"]["rigid_cluster_errors"],
                          "rmse_over_diagonal": auto["rmse_over_diagonal"],
                          "fixed_rmse_over_diagonal": fixed["rmse_over_diagonal"], "seconds": round(seconds, 1),
                          "fixed_seconds": round(fixed_seconds, 1),
                          "seconds_over_fixed": round(seconds / fixed_seconds, 2), "peak_mib": round(peak)}),
              flush=True)


if __name__ == "__main__":
    main()
