"""The paper's 20 directed cases against the golden model, one test each."""

import pytest

from driver import backend
from support.cases import CASES


@pytest.mark.parametrize("name,req,check", CASES, ids=[c[0] for c in CASES])
def test_directed(name, req, check):
    rsp = backend("golden").run(req)
    check(rsp[0])
