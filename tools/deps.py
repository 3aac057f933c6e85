"""Print the project's Python requirements (runtime + ``dev`` extra), one per line.

The Makefile installs these into the cached virtualenv before building the extension, so the
environment can be created without building the package first.
"""

import sys
from pathlib import Path

import tomllib

data = tomllib.loads(Path(sys.argv[1] if len(sys.argv) > 1 else "pyproject.toml").read_text())
project = data["project"]
for req in [*project["dependencies"], *project["optional-dependencies"]["dev"]]:
    print(req)
