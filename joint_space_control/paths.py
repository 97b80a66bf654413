"""Where the package's shared files (config/, the URDFs) are, however it was installed."""

from __future__ import annotations

import sys
from pathlib import Path

PACKAGE = "joint_space_control"


def share_dir() -> Path:
    """The package's share directory: the source tree when running from a checkout (editable
    install), else the ament index (colcon install), else ``<prefix>/share`` (pip)."""
    source = Path(__file__).resolve().parents[1]
    if (source / "package.xml").is_file() and (source / "config").is_dir():
        return source
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(PACKAGE))
    except (ImportError, LookupError, ValueError):
        pass
    prefix = Path(sys.prefix) / "share" / PACKAGE
    if (prefix / "config").is_dir():
        return prefix
    raise FileNotFoundError(f"cannot find the share directory of {PACKAGE}")


def config_file(name: str) -> Path:
    path = share_dir() / "config" / name
    if not path.is_file():
        raise FileNotFoundError(f"no config file {path}")
    return path
