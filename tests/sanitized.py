"""What `make sanitize` changes for the tests: it runs them with AddressSanitizer preloaded, which reserves
terabytes of address space and holds freed memory in quarantine, so resident sets and address-space limits
measure the sanitizer there, not the renderer."""

import os

import pytest

SANITIZED = os.environ.get("PCVR_SANITIZED") == "1"

measures_memory = pytest.mark.skipif(SANITIZED, reason="memory is not measurable under AddressSanitizer")
