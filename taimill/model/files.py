"""The user's files in and out: finding a preset, jar, pair or mill file by name or path
(`resolve`: a name is a bundled file of the package, a path the user's), telling their
kinds apart (`kind_of`), reading a preset, jar, pair file or CSV, and checking a path a
command will write before anything runs. Every OS, size and decoding problem
becomes the one-line ConfigError naming who gave the path (a file or the command line),
the key or option, the path and what is wrong.

Inputs must be regular files (not a folder, device or pipe) of at most MAX_INPUT_BYTES,
UTF-8 text. A file output needs an existing, writable folder; a folder output (figures,
recordings) is created with its parents, so its nearest existing ancestor must be a
writable folder. An existing output is refused unless the command was given --overwrite,
and even then it is replaced only if it is an output of the same kind that taimill wrote
and none of the command's inputs (`check_replaceable`): --overwrite must never cost a
user a file taimill did not make. The files a command reads are collected by `reads()`
for that check."""

from __future__ import annotations

import contextlib
import os
import stat
import tomllib
from pathlib import Path

from taimill.errors import ConfigError

MAX_INPUT_BYTES = 64 * 2**20  #: a preset, jar, pair file or measured CSV is far smaller
PACKAGE = Path(__file__).resolve().parent.parent  #: taimill/, home of the built-in materials
ROOT = PACKAGE.parent  #: the repository (its presets/ and jars/ link to the bundled ones)
DATA = PACKAGE / "data"  #: the bundled files, installed with the package
#: kind → the folders of its bundled files, searched in order for a NAME given without .toml
BUNDLED = {
    "preset": (DATA / "presets",),
    "jar": (DATA / "jars", DATA / "bowls"),
    "mill": (DATA / "mills",),
    "pair": (),  # built-in pairs are tables of materials.toml, not files
}
_READS: list[set] = []  #: the sets of the `reads()` blocks open now


@contextlib.contextmanager
def reads():
    """The resolved paths of every file read (read_bytes) inside the block, as a set:
    a command's inputs, which none of its outputs may replace."""
    seen: set[Path] = set()
    _READS.append(seen)
    try:
        yield seen
    finally:
        _READS.remove(seen)


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
        data = p.read_bytes()
        for seen in _READS:
            seen.add(p.resolve())
        return data
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


def bundled_names(kind: str) -> list[str]:
    """The names of the bundled files of a kind (a folder not installed holds none)."""
    return sorted({p.stem for folder in BUNDLED[kind] if folder.is_dir() for p in folder.glob("*.toml")})


def is_name(text: str) -> bool:
    """True if `text` names a bundled file (no .toml ending, no folder) rather than a path."""
    return not text.endswith(".toml") and "/" not in text and os.sep not in text


def resolve(name_or_path, kind: str, given_on_command_line: bool, base: Path | None = None, *,
            source=None, key: str | None = None) -> Path:
    """The file a preset, jar, pair file or mill file names. A name (no .toml ending, no
    folder: "CY", "p4-cy-steel") is the bundled file of that kind, looked up in
    BUNDLED[kind] in order; a name no folder holds is a ConfigError listing the known
    names. A path is taken as it is if absolute, else relative to the current folder
    when given on the command line, and to `base` (the folder of the file that names it)
    otherwise. `source` and `key` (default: "command line" or `base`, and `kind`) are
    who named it, for the error; a path is not checked here (reading it says why)."""
    text = os.fspath(name_or_path)
    here = Path(text) if given_on_command_line or base is None else Path(base) / text
    if os.path.isdir(here):  # a store folder where a file is meant: named as such (os.path: never raises)
        name_kind(kind, kind_of_path(here), text, source or ("command line" if given_on_command_line else base),
                  key or kind)
    if not is_name(text):
        p = Path(text)
        return p if p.is_absolute() or given_on_command_line or base is None else Path(base) / p
    for folder in BUNDLED[kind]:
        p = folder / f"{text}.toml"
        if not missing(p):
            return p
    if source is None:
        source = "command line" if given_on_command_line else base
    names = bundled_names(kind)
    known = f"known {kind}s: {', '.join(names)}" if names else f"no {kind}s are bundled"
    raise ConfigError(source, key or kind, text, f"no bundled {kind} of this name (a file name ends in .toml); {known}")


MILL_GEAR_KEYS = ("gear", "gears", "stations")  #: with plate_radius_mm: a mill file


def kind_of(data: dict) -> str | None:
    """Which kind of taimill file a TOML file's tables are, by their characteristic keys:
    "mill" (plate_radius_mm with a gear or stations key), "jar" (a [[profile]]), "pair"
    ([pair.NAME] or [contact.NAME] tables), "preset" (a [balls] table, or a jar or pair
    named by a string); None if none of these shows (an empty file)."""
    if "plate_radius_mm" in data and any(k.startswith(MILL_GEAR_KEYS) for k in data):
        return "mill"
    if "profile" in data:
        return "jar"
    if isinstance(data.get("pair"), dict) or isinstance(data.get("contact"), dict):
        return "pair"
    if isinstance(data.get("balls"), dict) or isinstance(data.get("jar"), str) or isinstance(data.get("pair"), str):
        return "preset"
    return None


#: kind → how a file of that kind is used
USES = {
    "preset": "run it with `taimill run {path}`",
    "jar": "use it with --jar {path} or jar = \"{path}\" in a preset",
    "pair": "use it with --pair {path} or pair = \"{path}\" in a preset",
    "mill": "use it with mill = \"{path}\" in a preset",
    "run store": "read it with `taimill analyse {path}` or `taimill report {path}`",
    "sweep store": "draw it with `taimill report {path}`",
}
#: kinds that are folders (zarr stores), told apart by the arrays they hold
STORE_LAYOUTS = {"sweep store": ("points", "table"), "run store": ("trajectory", "events")}


def kind_of_path(path) -> str | None:
    """Which kind of taimill file or folder `path` is: a store folder ("run store",
    "sweep store": a zarr group holding their arrays), a TOML file's kind (kind_of), or
    None (missing, unreadable, or none of these)."""
    p = Path(path)
    try:
        if os.path.isdir(p):
            if not ((p / "zarr.json").is_file() or (p / ".zgroup").is_file()):
                return None
            return next((k for k, arrays in STORE_LAYOUTS.items() if all((p / a).is_dir() for a in arrays)), None)
        if os.path.isfile(p) and p.suffix == ".toml" and p.stat().st_size < (1 << 20):
            return kind_of(tomllib.loads(p.read_text(encoding="utf-8")))
    except (OSError, ValueError):  # unreadable, not UTF-8, not TOML: the reader says why
        return None
    return None


def name_kind(kind: str, found: str | None, path, source, key) -> None:
    """Refuse `path`, given where a `kind` is expected, if it is of another known kind
    (kind_of_path), in one line that says what it is and how to use it."""
    if found is not None and found != kind:
        noun = kind if kind.endswith("store") else f"{kind} file"
        what = found if found.endswith("store") else f"{found} file"
        raise ConfigError(source, key, str(path), f"this is a {what}, not a {noun}; " + USES[found].format(path=path))


def check_kind(data: dict, kind: str, path, source, key) -> None:
    """Refuse, in one line that says how to use it, a file of another kind than `kind`
    (a jar file given as a preset…); a file of no recognisable kind is left to the
    loader's key checks."""
    name_kind(kind, kind_of(data), path, source, key)


def _inside(path: Path, folder: Path) -> bool:
    try:
        return path.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError):  # a symlink loop: not followed
        return False


def check_replaceable(path, key, what: str, ours, *, inputs=(), source: str = "command line") -> None:
    """Refuse (ConfigError naming the path and why) to replace an existing `path` unless
    it is an output of this kind that taimill wrote: `ours(path)` is true (a run or sweep
    store by its attributes, a case by its manifest, a recording or figure by its
    format…). Never replaced: an input of the command (`inputs`: paths it reads) or a
    folder holding one, something that is neither a regular file nor a folder (a device,
    a pipe), or anything `ours` does not recognise, such as a folder of other files.
    An empty folder holds nothing to lose and may be replaced."""
    p = Path(path)
    if not os.path.lexists(p):
        return

    def bad(why):
        return ConfigError(source, key, str(path), f"{why}; not replaced")

    for given in map(Path, inputs):
        if _inside(given, p):
            raise bad("is an input of this command" if given.resolve() == p.resolve()
                      else f"holds {given}, an input of this command")
    try:
        st = os.stat(p)
    except OSError as err:
        raise bad(f"cannot be examined ({err.strerror or err})") from None
    if stat.S_ISDIR(st.st_mode):
        try:
            with os.scandir(p) as entries:
                empty = not any(entries)
        except OSError as err:
            raise bad(f"cannot be examined ({err.strerror or err})") from None
        if empty:
            return
    elif not stat.S_ISREG(st.st_mode):
        raise bad(f"is not a regular file or folder (a device or pipe), not a {what}")
    if not ours(p):
        raise bad(f"exists and is not a {what} written by taimill")


def check_output(text, key, *, overwrite: bool | None = False, folder: bool = False, suffixes: tuple[str, ...] = (),
                 source: str = "command line", what: str = "output", ours=None, inputs=()) -> Path:
    """The path a command will write, checked before anything runs. overwrite None:
    an existing path is the caller's business (stores that resume; they check it with
    check_replaceable); False: refused; True: replaced only if check_replaceable lets
    it (`what`, `ours`, `inputs`: see there; `ours` None: nothing existing is ours)."""
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
            if overwrite:
                check_replaceable(p, key, what, ours or (lambda _: False), inputs=inputs, source=source)
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
