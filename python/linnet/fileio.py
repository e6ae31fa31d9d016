"""Reading and writing the project's small text files with errors that name the file (one exception type for the
whole Python package: InputError, a ValueError)."""
from __future__ import annotations

import json
from pathlib import Path


class InputError(ValueError):
    """A file, array or argument Linnet cannot use; the message names the file and line where it can."""


def read_text_file(path: Path, what: str, name_if_missing: bool = False) -> str:
    """The text of a UTF-8 file; InputError naming the file when it is missing (with `what` if name_if_missing), a
    directory ("expected <what>"), not text or unreadable."""
    try:
        return path.read_text(encoding="utf-8", errors="strict")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file" + (f" ({what})" if name_if_missing else "")) from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, expected {what}") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not a text file ({e.reason} at byte {e.start})") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None


def write_json_file(path: Path, data) -> None:
    """Write `data` as indented JSON (creating the parent folder); InputError naming the file if it cannot."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    except OSError as e:
        raise InputError(f"{path}: cannot write JSON ({e.strerror})") from None
