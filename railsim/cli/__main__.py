"""``python -m railsim.cli`` = the ``railsim`` command."""

import sys

from railsim.cli.launch import main

sys.exit(main())
