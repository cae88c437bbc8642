import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))   # shared helpers: cases.py, scalar reference

import os  # noqa: E402

# The suite builds the RTL harness without profile-guided optimisation: a PGO build compiles the
# model twice and runs a training workload, which for five configurations would double the suite's
# cold-cache time. The default (PGO) build is what `rayflex` uses; tests/test_pgo.py builds and
# checks it explicitly, and every PGO build checks its own final library against golden.
os.environ.setdefault("RAYFLEX_PGO", "0")
