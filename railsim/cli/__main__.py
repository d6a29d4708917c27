"""``python -m railsim.cli`` = the ``railsim`` command (Ctrl-C while it starts: one line, exit 130)."""

import sys

try:
    from railsim.cli.launch import main
except KeyboardInterrupt:
    sys.stderr.write("railsim: interrupted\n")
    sys.exit(130)

sys.exit(main())
