"""Read ProcTHOR-schema houses from files, folders and AI2's ``prior`` package.

Accepted layouts, chosen by the path:

- ``X.json`` / ``X.json.gz`` holding one house (a JSON object; id: the house's own ``id``,
  else the file stem ``X``), a list of houses (ids ``X-00000``, ``X-00001``, ...), or a
  split dictionary ``{"train": [...], "val": [...]}`` read with ``split=`` (ids
  ``X-train-00000``, ...);
- ``X.jsonl`` / ``X.jsonl.gz``: one house per line (ids ``X-<0-based line index, 5 digits>``;
  blank lines are skipped but keep their number);
- a folder: every ``*.json`` / ``*.json.gz`` file in it, in sorted file-name order, one house
  per file (id: the house's own ``id``, else the file name without ``.json``/``.json.gz``);
- ``prior.load_dataset(name)[split]`` (ids ``<name>-<split>-<index, 5 digits>``).

A house that carries its own non-empty ``id`` keeps it in every layout except ``prior``.
Items of lists and split dictionaries may also be JSON strings (as ``prior`` stores them).

Problems of one house become a :class:`HouseRecord` holding a :class:`HouseError`, so that
house fails alone: a ``.jsonl`` line that is not valid JSON (id ``X:line<N>``, 1-based line
number), a folder file that is not valid JSON or not one house. Problems of the whole input
raise one line naming the path: a missing path, an unknown suffix, a ``.json`` file that is
not valid JSON, a split dictionary without the chosen split (the error lists the splits), a
``split`` given for a file that has none, an input with no houses, and two houses with one
id (the error names both places).
"""

from __future__ import annotations

import gzip
import json
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envs.files import regular_file
from envs.world.classes import ROOM_TYPE_TO_CLASS
from envs.world.house import House, HouseError, validate_house

#: Suffixes of the files a folder layout reads.
FOLDER_SUFFIXES = (".json.gz", ".json")


@dataclass(frozen=True)
class HouseRecord:
    """One house of an input: its id, where it came from, and its parsed dict or why not.

    Attributes:
        id: the house id.
        source: where it was read, e.g. ``"houses.jsonl line 3"`` or ``"houses.json [train][4]"``.
        data: the house dict exactly as parsed (``None`` when unreadable).
        error: why the house cannot be read, or ``None``.
    """

    id: str
    source: str
    data: Any = None
    error: HouseError | None = None

    def house(
        self,
        validate: bool = True,
        room_types: Mapping[str, str] = ROOM_TYPE_TO_CLASS,
        classes: Sequence[str] | None = None,
    ) -> House:
        """The house, validated against ``room_types`` and ``classes``.

        Returns:
            :class:`House` whose ``data`` is :attr:`data` itself (not copied).

        Raises:
            HouseError: the record's read error, or the first validation problem.
        """
        if self.error is not None:
            e = self.error
            raise HouseError(e.house_id, e.field, e.problem)
        if validate:
            validate_house(self.data, self.id, room_types, classes)
        return House(self.id, self.data)


def _stem(name: str) -> str:
    """File name without its house suffix (``a.json.gz`` -> ``a``)."""
    for suffix in (".jsonl.gz", ".json.gz", ".jsonl", ".json"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def _own_id(data: Any, default: str) -> str:
    """The house's own ``id`` when it has a non-empty one, else ``default``."""
    if isinstance(data, Mapping) and data.get("id") not in (None, ""):
        return str(data["id"])
    return default


def split_keys(data: Any) -> list[str] | None:
    """Split names when ``data`` is a split dictionary (an object with no ``rooms`` whose
    values are all lists), else ``None``."""
    if (isinstance(data, Mapping) and data and "rooms" not in data
            and all(isinstance(v, list) for v in data.values())):
        return [str(k) for k in data]
    return None


def _json_error(house_id: str, source: str, e: json.JSONDecodeError) -> HouseError:
    return HouseError(house_id, source, f"not valid JSON: {e.msg} (column {e.colno})")


def _item(item: Any, house_id: str, source: str) -> HouseRecord:
    """A list or split item: a house dict, or a JSON string of one (as ``prior`` stores them)."""
    if isinstance(item, str):
        try:
            item = json.loads(item)
        except json.JSONDecodeError as e:
            return HouseRecord(house_id, source, error=_json_error(house_id, source, e))
    return HouseRecord(_own_id(item, house_id), source, item)


def _read_text(path: Path) -> str:
    opener = gzip.open if path.name.endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8") as f:
            return f.read()
    except (OSError, EOFError, UnicodeDecodeError, zlib.error) as e:  # zlib.error: a damaged .gz (a flipped bit)
        raise ValueError(f"house file {path}: cannot be read ({e})") from None


def _jsonl(path: Path, prefix: str) -> Iterator[HouseRecord]:
    opener = gzip.open if path.name.endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8") as f:
            for i, line in enumerate(f):
                if not line.strip():
                    continue
                source = f"{path} line {i + 1}"
                try:
                    data = json.loads(line)
                except json.JSONDecodeError as e:
                    hid = f"{prefix}:line{i + 1}"
                    yield HouseRecord(hid, source, error=_json_error(hid, source, e))
                    continue
                yield HouseRecord(_own_id(data, f"{prefix}-{i:05d}"), source, data)
    except (OSError, EOFError, UnicodeDecodeError, zlib.error) as e:  # zlib.error: a damaged .gz (a flipped bit)
        raise ValueError(f"house file {path}: cannot be read ({e})") from None


def _json(path: Path, prefix: str, split: str | None) -> Iterator[HouseRecord]:
    text = _read_text(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"house file {path}: not valid JSON: {e.msg} (line {e.lineno}, column {e.colno})") from None
    splits = split_keys(data)
    if splits is not None:
        full = [k for k in splits if data[k]]  # the error lines list only splits that hold houses
        if not full:
            raise ValueError(f"house file {path}: every split ({splits}) is empty; no houses")
        if split is None:
            raise ValueError(f"house file {path} holds the splits {full}; choose one with split (env.split)")
        if split not in data or not data[split]:
            why = "no split" if split not in data else "an empty split"
            raise ValueError(f"house file {path}: {why} {split!r}; splits with houses: {full}")
        for i, item in enumerate(data[split]):
            yield _item(item, f"{prefix}-{split}-{i:05d}", f"{path} [{split}][{i}]")
        return
    _no_split(path, split)
    if isinstance(data, list):
        for i, item in enumerate(data):
            yield _item(item, f"{prefix}-{i:05d}", f"{path} [{i}]")
    else:
        yield HouseRecord(_own_id(data, prefix), str(path), data)


def _folder(path: Path) -> Iterator[HouseRecord]:
    files = sorted(p for p in path.iterdir() if p.is_file() and p.name.endswith(FOLDER_SUFFIXES))
    for p in files:
        stem = _stem(p.name)
        source = str(p)
        try:
            data = json.loads(_read_text(p))
        except json.JSONDecodeError as e:
            yield HouseRecord(stem, source, error=HouseError(
                stem, source, f"not valid JSON: {e.msg} (line {e.lineno}, column {e.colno})"))
            continue
        except ValueError as e:
            yield HouseRecord(stem, source, error=HouseError(stem, source, str(e)))
            continue
        if isinstance(data, list):
            problem = f"expected one house (a JSON object) per file in a folder, got a list of {len(data)}"
            yield HouseRecord(stem, source, error=HouseError(stem, source, problem))
        elif split_keys(data) is not None:
            problem = (f"holds a split dictionary {split_keys(data)}; give this file itself as the path, "
                       "with split, instead of its folder")
            yield HouseRecord(stem, source, error=HouseError(stem, source, problem))
        else:
            yield HouseRecord(_own_id(data, stem), source, data)


def _no_split(path: Path, split: str | None) -> None:
    if split is not None:
        raise ValueError(
            f"house input {path}: split {split!r} given, but only a split dictionary "
            '({"train": [...], "val": [...]}) has splits; leave split unset (env.split=null)')


def iter_house_records(path: str | Path, prefix: str | None = None, split: str | None = None) -> Iterator[HouseRecord]:
    """Every house of a house file or folder, in order, as :class:`HouseRecord` (lazily).

    Args:
        path: a ``.json``, ``.json.gz``, ``.jsonl``, ``.jsonl.gz`` file or a folder of
            ``.json``/``.json.gz`` files (see the module docstring).
        prefix: id prefix for houses without their own id (default: the file's stem).
        split: the split to read from a split dictionary; must be ``None`` otherwise.

    Returns:
        iterator of :class:`HouseRecord`; records of unreadable houses carry their error.

    Raises:
        FileNotFoundError, ValueError: a problem of the whole input (named in one line),
        or a house id seen twice (the error names both places).
    """
    path = Path(path).expanduser()
    if not path.exists():
        raise FileNotFoundError(f"house file not found: {path}")
    name = path.name
    prefix = prefix or name.split(".")[0]
    if not path.is_dir():  # a FIFO or a device (/dev/zero) is refused by stat before anything opens it
        regular_file(path, "house file")
    if path.is_dir():
        _no_split(path, split)
        records = _folder(path)
    elif name.endswith((".jsonl", ".jsonl.gz")):
        _no_split(path, split)
        records = _jsonl(path, prefix)
    elif name.endswith((".json", ".json.gz")):
        records = _json(path, prefix, split)
    else:
        raise ValueError(
            f"house file {path}: expected .json, .json.gz, .jsonl, .jsonl.gz or a folder of .json/.json.gz files")
    seen: dict[str, str] = {}
    for rec in records:
        if rec.id in seen:
            raise ValueError(
                f"house id {rec.id!r} appears twice: {seen[rec.id]} and {rec.source}; every house needs its own id")
        seen[rec.id] = rec.source
        yield rec
    if not seen:
        what = "no .json or .json.gz house files" if path.is_dir() else "no houses"
        raise ValueError(f"house input {path} holds {what}" + (f" in split {split!r}" if split else ""))


def read_house_records(
    path: str | Path, start: int = 0, stop: int | None = None, prefix: str | None = None, split: str | None = None,
) -> list[HouseRecord]:
    """Houses ``[start:stop]`` of an input as records (indices count every house, readable
    or not); reading stops at ``stop``. Arguments and errors as :func:`iter_house_records`.

    Returns:
        list of :class:`HouseRecord`, in input order.
    """
    if start < 0 or (stop is not None and stop < 0):
        raise ValueError(f"house range start={start}, stop={stop}: expected non-negative indices")
    out = []
    for i, rec in enumerate(iter_house_records(path, prefix, split)):
        if stop is not None and i >= stop:
            break
        if i >= start:
            out.append(rec)
    return out


def iter_house_file(
    path: str | Path, prefix: str | None = None, validate: bool = True, split: str | None = None,
) -> Iterator[House]:
    """Houses of a house file or folder, strictly: the first unreadable or (with
    ``validate``) invalid house raises its :class:`HouseError`.

    Returns:
        iterator of :class:`House`.
    """
    for rec in iter_house_records(path, prefix, split):
        yield rec.house(validate=validate)


def load_houses(
    path: str | Path,
    start: int = 0,
    stop: int | None = None,
    prefix: str | None = None,
    validate: bool = True,
    split: str | None = None,
) -> list[House]:
    """Houses ``[start:stop]`` of a house file or folder (indices count every house);
    strict as :func:`iter_house_file`.

    Returns:
        list of :class:`House`.
    """
    return [r.house(validate=validate) for r in read_house_records(path, start, stop, prefix, split)]


# ---- prior


def prior_splits(ds: Any) -> list[str]:
    """Names of the splits of a ``prior`` ``DatasetDict`` that hold houses.

    prior's ``DatasetDict`` has only ``__getitem__`` (no ``keys``, ``__iter__`` or
    ``__contains__``) and knows the splits train, val and test, raising ``KeyError`` for an
    absent one; a plain mapping is listed directly. Splits with no house are left out.

    Returns:
        list of split names.
    """
    names = [str(k) for k in ds] if isinstance(ds, Mapping) else ["train", "val", "test"]
    out = []
    for name in names:
        try:
            n = len(ds[name])
        except KeyError:
            continue
        if n:
            out.append(name)
    return out


def prior_records(ds: Any, dataset: str, split: str, start: int = 0, stop: int | None = None) -> list[HouseRecord]:
    """Houses ``[start:stop]`` of split ``split`` of a ``prior`` ``DatasetDict``.

    A house whose stored JSON does not parse (``LazyJsonDataset`` parses on access) becomes
    a record with its error, so it fails alone.

    Returns:
        list of :class:`HouseRecord` with ids ``<dataset>-<split>-<index, 5 digits>``.

    Raises:
        ValueError: ``split`` is not in ``ds`` or holds no house (the message lists the splits
            that hold houses).
    """
    if start < 0 or (stop is not None and stop < 0):
        raise ValueError(f"house range start={start}, stop={stop}: expected non-negative indices")
    try:
        data = ds[split]
    except KeyError:
        raise ValueError(f"{dataset} has no split {split!r}; splits with houses: {prior_splits(ds)}") from None
    if not len(data):
        raise ValueError(f"{dataset}: split {split!r} holds no houses; splits with houses: {prior_splits(ds)}")
    stop = len(data) if stop is None else min(stop, len(data))
    out = []
    for i in range(start, stop):
        hid, source = f"{dataset}-{split}-{i:05d}", f"prior {dataset} [{split}][{i}]"
        try:
            out.append(HouseRecord(hid, source, data[i]))
        except json.JSONDecodeError as e:
            out.append(HouseRecord(hid, source, error=_json_error(hid, source, e)))
    return out


def load_prior_dataset(dataset: str = "procthor-10k", revision: str | None = None) -> Any:
    """``prior.load_dataset(dataset)`` (needs ``pip install 'roomseg-bench[thor]'``, network
    access and git-lfs on first use; cached in ``~/.prior``).

    Returns:
        prior's ``DatasetDict``.
    """
    try:
        import prior  # noqa: PLC0415
    except ImportError:
        raise ImportError("loading ProcTHOR-10k needs the 'prior' package: pip install 'roomseg-bench[thor]'") from None
    kwargs = {"revision": revision} if revision else {}
    return prior.load_dataset(dataset, **kwargs)


def load_prior_houses(
    dataset: str = "procthor-10k", split: str = "train", start: int = 0, stop: int | None = 100,
    revision: str | None = None, validate: bool = True,
) -> list[House]:
    """Houses ``[start:stop]`` of ``split`` from AI2's ``prior`` package, strictly (the first
    invalid house raises). The paper uses ``procthor-10k`` train[0:100].

    Returns:
        list of :class:`House`.
    """
    records = prior_records(load_prior_dataset(dataset, revision), dataset, split, start, stop)
    return [r.house(validate=validate) for r in records]


__all__ = [
    "HouseRecord", "iter_house_records", "read_house_records", "iter_house_file", "load_houses",
    "prior_splits", "prior_records", "load_prior_dataset", "load_prior_houses", "split_keys",
]
