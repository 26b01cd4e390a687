"""Suite-wide set-up."""

from __future__ import annotations

import signal

# A shell that starts the suite in the background without job control (`make test &`, `nohup`,
# some CI runners) leaves SIGINT ignored, and every process started from here would inherit that:
# the Ctrl-C tests would then test the shell, not orbitsim. Give this process the disposition an
# interactive terminal gives Python; its children get the default again on exec.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
