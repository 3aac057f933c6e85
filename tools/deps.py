"""Print the project's Python requirements, one per line: runtime + the ``dev`` extra, or with
``--only EXTRA`` just that optional extra (e.g. ``bench``).

The Makefile installs these into the cached virtualenv before building the extension, so the
environment can be created without building the package first.
"""

import sys
from pathlib import Path

import tomllib

args = sys.argv[1:]
only = None
if args[:1] == ["--only"]:
    only, args = args[1], args[2:]
data = tomllib.loads(Path(args[0] if args else "pyproject.toml").read_text())
project = data["project"]
extras = project["optional-dependencies"]
reqs = extras[only] if only else [*project["dependencies"], *extras["dev"]]
for req in reqs:
    print(req)
