"""``python -m railsim.cli`` = the ``railsim`` command."""

import sys

from railsim.cli.main import main

sys.exit(main())
