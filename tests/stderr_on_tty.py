#!/usr/bin/env python3
"""tests/stderr_on_tty.py STDOUT_FILE COMMAND... — runs COMMAND with its
stderr on a pseudo-terminal (so isatty(2) is true, as on a user's screen)
and its stdout redirected to STDOUT_FILE; prints what the terminal received
and exits with COMMAND's status. Used by tests/cli_output.sh."""
import os
import pty
import subprocess
import sys

master, slave = pty.openpty()
with open(sys.argv[1], "wb") as out:
    child = subprocess.Popen(sys.argv[2:], stdin=subprocess.DEVNULL, stdout=out, stderr=slave)
os.close(slave)
received = b""
while True:
    try:
        chunk = os.read(master, 65536)
    except OSError:  # EIO: the child closed the terminal
        break
    if not chunk:
        break
    received += chunk
status = child.wait()
sys.stdout.buffer.write(received)
sys.exit(status)
