"""Suite-wide set-up: the import path of the suite's folders, and the SIGINT disposition.

The tests mirror the package: ``tests/integrators/`` tests ``orbitsim/integrators/``, and so on;
tests of the top-level modules (``runner``, ``sampling``, ...) and of the package as a whole sit
here. Test folders are not packages (a ``tests/io`` package would shadow the standard library's
``io``), so every test module keeps a unique file name and is imported by that name.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

# The shared helpers here (naive.py, forces_helpers.py, ensemble_helpers.py, browser.py) are imported by
# name from every folder, and some test modules import another's fixtures and constants by module name
# (``from test_checkpoint_kill import assert_same_datasets``), as they did when the suite was one
# folder. Put this folder and each test folder on the path, so such an import does not depend on
# which folder pytest happened to collect first.
TESTS = Path(__file__).resolve().parent
for folder in (TESTS, *sorted(p for p in TESTS.iterdir() if p.is_dir() and p.name.isidentifier())):
    if str(folder) not in sys.path:
        sys.path.insert(1, str(folder))

# A shell that starts the suite in the background without job control (`make test &`, `nohup`,
# some CI runners) leaves SIGINT ignored, and every process started from here would inherit that:
# the Ctrl-C tests would then test the shell, not orbitsim. Give this process the disposition an
# interactive terminal gives Python; its children get the default again on exec.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
