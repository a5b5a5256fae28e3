"""`small_dense`: every BLAS library of the process limited inside the block, restored after."""

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json
from tanksynth.analysis.blas import small_dense
with small_dense():
    from threadpoolctl import threadpool_info
    inside = [(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]
after = [(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]
print(json.dumps({"inside": inside, "after": after}))
"""


@pytest.mark.slow
def test_small_dense_limits_every_blas_library_and_restores_them():
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env,
                         check=True, timeout=120).stdout
    got = json.loads(out)
    inside = dict(got["inside"])
    assert len(inside) >= 1
    assert all(n == 1 for n in inside.values()), got
    # the same libraries after the block, back to their own thread counts
    assert set(dict(got["after"])) == set(inside)
    if (os.cpu_count() or 1) > 1:
        assert any(n > 1 for n in dict(got["after"]).values()), got
