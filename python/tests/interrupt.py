"""Runs Python code in a child process and interrupts it as Ctrl-C would."""

import signal
import subprocess
import sys
import time


def interrupted_output(code, *args, after=1.0):
    """Runs ``code`` (which prints "started" when the long call begins) with ``args``, sends
    SIGINT ``after`` seconds after "started", and returns what it printed after that."""
    child = subprocess.Popen([sys.executable, "-c", code, *map(str, args)],
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(after)
        child.send_signal(signal.SIGINT)
        out, _ = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    return out.strip()
