"""Reading a TOML input file with errors that name the file (Python 3.11's tomllib, or tomli)."""

from __future__ import annotations

from pathlib import Path


def read_toml(path, what: str) -> dict:
    """The TOML file at ``path`` as a dict; ``what`` names it in the errors ("wedge file"): a
    ValueError when tomllib/tomli is missing, the file is absent or it is not valid TOML."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        try:
            import tomli as tomllib
        except ImportError as exc:
            raise ValueError(f"reading a {what} needs Python 3.11 (tomllib) or pip install tomli") from exc
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} not found: {path}")
    with open(path, "rb") as fh:
        try:
            return tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML: {exc}") from None
