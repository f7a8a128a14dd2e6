"""Quasi-static modal analysis of sandwich-2d from Python.

Run: python examples/run_sandwich.py [OUT_DIR]
"""
import sys

import qsma
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.output.files import prepare_output_dir, write_all


def main(out="out/example-api"):
    model = sandwich_2d(refine=1)
    levels = Levels.log("tip", 1e-6, 1e-3, 51)        # the spec's 51 levels
    res = qsma.run(model, mode=0, levels=levels, method="basket", direct_loop=True)
    if not res.success:
        print(res.message)
        return 1
    print(f"f0 = {res.f0_hz:.3f} Hz")
    print(f"{'tip [m]':>10} {'f [Hz]':>9} {'zeta':>10}")
    for k in range(0, res.n_levels, 10):
        print(f"{res.tip[k]:10.3e} {res.f_hz[k]:9.3f} {res.zeta[k]:10.3e}")
    dl = res.direct_loop
    print(f"dissipation at the largest level: direct {dl.dissipation:.5g}, "
          f"Masing {dl.dissipation_masing:.5g}")
    paths = write_all(res, prepare_output_dir(out))
    print("written:", ", ".join(str(p) for p in paths.values()))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
