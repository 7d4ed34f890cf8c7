"""Collection from any clone: the repository root is the extension's package, not a test package.

The repository root holds the extension's `__init__.py` (Blender loads the root as a package),
so pytest would collect the root as a Package and import that `__init__.py` as a test module:
under the name of the clone's folder, a second copy of the add-on, and in a clone whose folder
name is not a Python identifier (`/tmp/ci-1`) "attempted relative import with no known parent
package". Collected as a plain directory instead, nothing of the root is imported by pytest;
tests import `prt_addon` through the `pythonpath` setting. A plugin (loaded by tests/conftest.py
through pytest_plugins), not a conftest hook, because conftest hooks apply only below their folder.
"""

import pytest


@pytest.hookimpl(tryfirst=True)
def pytest_collect_directory(path, parent):
    if path == parent.config.rootpath and (path / "blender_manifest.toml").is_file():
        return pytest.Dir.from_parent(parent, path=path)
    return None
