"""``python -m railsim.compile_core``: compile the step loop's modules to C (:mod:`railsim.native`), or say which
modules this interpreter loads.

    python -m railsim.compile_core [--if-stale]    # into build/native/ (make native)
    python -m railsim.compile_core --status        # "compiled (18 modules, ...)" or "interpreted (why)"
"""

from __future__ import annotations

import argparse

from railsim import native


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m railsim.compile_core", description=__doc__.splitlines()[0])
    parser.add_argument("--if-stale", action="store_true", help="only when the sources changed since the last build")
    parser.add_argument("--status", action="store_true", help="say whether this interpreter loads the compiled core")
    args = parser.parse_args(argv)
    if args.status:
        print(native.STATUS)
        return 0
    return native.build(if_stale=args.if_stale)


if __name__ == "__main__":
    raise SystemExit(main())
