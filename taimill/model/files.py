"""The user's files in and out: reading a preset, jar, pair file or CSV, and checking a
path a command will write before anything runs. Every OS, size and decoding problem
becomes the one-line ConfigError naming who gave the path (a file or the command line),
the key or option, the path and what is wrong.

Inputs must be regular files (not a folder, device or pipe) of at most MAX_INPUT_BYTES,
UTF-8 text. A file output needs an existing, writable folder; a folder output (figures,
recordings) is created with its parents, so its nearest existing ancestor must be a
writable folder. An existing output is refused unless the command was given --overwrite."""

from __future__ import annotations

import os
import stat
import tomllib
from pathlib import Path

from taimill.errors import ConfigError

MAX_INPUT_BYTES = 64 * 2**20  #: a preset, jar, pair file or measured CSV is far smaller
PACKAGE = Path(__file__).resolve().parent.parent  #: taimill/, home of the built-in materials
ROOT = PACKAGE.parent  #: the repository, home of jars/ and presets/


def check_path_text(text, source, key, what: str = "a file name") -> str:
    """text if it can name a file: not empty or blank, no NUL character."""
    if not isinstance(text, (str, os.PathLike)):
        raise ConfigError(source, key, text, f"must be {what} (a string)")
    text = os.fspath(text)
    if not text.strip():
        raise ConfigError(source, key, text, f"must be {what}, not empty")
    if "\0" in text:
        raise ConfigError(source, key, text, f"must be {what} without NUL characters")
    return text


def missing(path) -> bool:
    """True if there is no such file (nor a link) at path; a path the OS refuses for
    another reason (a name too long, a loop) is not missing: reading it says why."""
    try:
        os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return True
    except (OSError, ValueError):
        return False
    return False


def read_bytes(path, source, key, what: str = "file") -> bytes:
    """The bytes of the regular file at `path` (see the module doc)."""
    text = check_path_text(str(path) if isinstance(path, Path) else path, source, key)
    p = Path(text)

    def bad(why):
        return ConfigError(source, key, text, why)

    try:
        st = p.stat()
        if stat.S_ISDIR(st.st_mode):
            raise bad(f"cannot read: is a folder; need a {what}")
        if not stat.S_ISREG(st.st_mode):
            raise bad(f"cannot read: not a regular file (a device or pipe); need a {what}")
        if st.st_size > MAX_INPUT_BYTES:
            raise bad(f"cannot read: {st.st_size / 2**20:.0f} MiB; need a {what} of at most {MAX_INPUT_BYTES // 2**20} MiB")
        return p.read_bytes()
    except FileNotFoundError:
        raise bad(f"cannot read: no such {what}") from None
    except NotADirectoryError:
        raise bad("cannot read: a folder on the path is a file") from None
    except PermissionError:
        raise bad(f"cannot read: permission denied; need a readable {what}") from None
    except OSError as err:
        raise bad(f"cannot read: {err.strerror or err}") from None


def read_text(path, source, key, what: str = "file") -> str:
    """UTF-8 text of a file (a leading byte-order mark is dropped, as spreadsheets write it)."""
    data = read_bytes(path, source, key, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ConfigError(source, key, str(path), f"cannot read: not a UTF-8 text {what} (byte {err.start} is {data[err.start]:#04x})") from None


def read_toml(path, source, key, what: str = "TOML file") -> dict:
    """A TOML file's tables; a syntax error names the file itself."""
    text = read_text(path, source, key, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(path, key, str(path), f"not valid TOML ({err})") from None
    except RecursionError:
        raise ConfigError(path, key, str(path), "not valid TOML (arrays or tables nested too deeply)") from None


def check_output(text, key, *, overwrite: bool | None = False, folder: bool = False, suffixes: tuple[str, ...] = (),
                 source: str = "command line") -> Path:
    """The path a command will write, checked before anything runs. overwrite None:
    an existing path is the caller's business (stores that resume); False: refused."""
    text = check_path_text(text, source, key, "a folder name" if folder else "a file name")
    p = Path(text)

    def bad(why):
        return ConfigError(source, key, text, why)

    if suffixes and p.suffix.lower() not in suffixes:
        raise bad(f"the file name must end in {' or '.join(suffixes)}")
    try:
        exists = p.exists() or p.is_symlink()
        if exists:
            if folder and not p.is_dir():
                raise bad("exists and is not a folder")
            if not folder and overwrite is not None and p.is_dir():
                raise bad("is a folder; need a file name")
            if overwrite is False:
                raise bad("exists; pass --overwrite to replace it")
            if not os.access(p, os.W_OK):
                raise bad("exists and is not writable")
            return p
        parent = p.absolute().parent
        if not folder:
            if not parent.exists():
                raise bad(f"the folder {parent} does not exist")
        else:
            while not parent.exists() and parent != parent.parent:
                parent = parent.parent
        if not parent.is_dir():
            raise bad(f"{parent} is not a folder")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise bad(f"the folder {parent} is not writable")
    except OSError as err:
        raise bad(f"cannot use this path ({err.strerror or err})") from None
    return p


def csv_cells(line: str, source, key) -> list[str]:
    """The cells of one CSV line; the csv module's own errors (an over-long field) as ConfigError."""
    import csv

    try:
        return next(csv.reader([line]), [])
    except csv.Error as err:
        raise ConfigError(source, key, line, f"not a CSV line ({err})") from None
