"""Configuration files: the shared pydantic base, one-line errors, TOML in and out.

Scenarios (:mod:`crlbswarm.scenario`), the parameter sets they are made of (the control gains
of :mod:`crlbswarm.control`) and campaign specs (:mod:`crlbswarm.campaign`) are pydantic
models built on :class:`ConfigModel`: frozen, strict, unknown keys refused. This module reads
them from TOML text, turns pydantic's errors into one :class:`~crlbswarm.errors.ConfigError`
line naming the dotted field, and writes a model back as TOML, each value commented with its
field's description.
"""

from __future__ import annotations

import json
import math
import os
import re
import secrets
import stat
import sys
import textwrap
import types
import typing
from pathlib import Path
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .errors import ConfigError, FieldError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib  # type: ignore[import-not-found, no-redef, unused-ignore]

__all__ = [
    "ConfigModel",
    "PositiveFloat",
    "describe",
    "model_to_toml",
    "read_toml",
    "read_toml_file",
    "validate",
]

Model = TypeVar("Model", bound=BaseModel)

#: Largest configuration file read, bytes (a scenario with thousands of obstacles is far
#: below; an endless file such as ``/dev/zero`` stops here).
MAX_FILE_BYTES = 4 * 2**20

#: Deepest nesting of tables and arrays in a configuration file (scenarios need 3).
MAX_DEPTH = 16


#: A finite number > 0 (the type of most physical parameters of the configuration models).
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class ConfigModel(BaseModel):
    """Base of every configuration model: frozen, strict types, unknown keys refused.

    A subclass declares each field once (type, default and a ``description`` with its unit);
    its docstring's numpydoc ``Parameters`` section is generated from those declarations,
    like the comments of its TOML form (:func:`model_to_toml`).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        if cls.model_fields and "\n    Parameters\n" not in (cls.__doc__ or ""):
            cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n\n" + _parameters_section(cls)


def read_toml(text: str, source: str, error: type[ConfigError] = ConfigError) -> dict[str, Any]:
    """Parse TOML text.

    Parameters
    ----------
    text : str
        The document.
    source : str
        Name of the document in error messages (a file name).
    error : type, default ConfigError
        The error to raise (a subclass of :class:`~crlbswarm.errors.ConfigError`).

    Returns
    -------
    dict
        The parsed document.

    Raises
    ------
    ConfigError
        If the text is not valid TOML.
    """
    if len(text) > MAX_FILE_BYTES:
        raise error(source, "", f"{len(text)} characters, more than the {MAX_FILE_BYTES} allowed")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(source, "", f"invalid TOML: {exc}") from None
    except RecursionError:
        raise error(source, "", "invalid TOML: nested too deeply") from None
    if _depth(data) > MAX_DEPTH:
        raise error(source, "", f"tables or arrays nested more than {MAX_DEPTH} deep")
    return data


def _depth(value: Any, level: int = 0) -> int:
    """Nesting depth of tables and arrays (stops counting past :data:`MAX_DEPTH`)."""
    if level > MAX_DEPTH:
        return level
    if isinstance(value, dict):
        return max((_depth(v, level + 1) for v in value.values()), default=level + 1)
    if isinstance(value, list):
        return max((_depth(v, level + 1) for v in value), default=level + 1)
    return level


def read_toml_file(
    path: str | Path, error: type[ConfigError] = ConfigError
) -> tuple[str, dict[str, Any]]:
    """Read and parse a TOML file.

    Parameters
    ----------
    path : str or path-like
        The file.
    error : type, default ConfigError
        The error to raise (a subclass of :class:`~crlbswarm.errors.ConfigError`).

    Returns
    -------
    text : str
        The file's text.
    data : dict
        The parsed document.

    Raises
    ------
    ConfigError
        If the file cannot be read or is not valid TOML (its source is the file name).
    """
    try:
        # Non-blocking, so that opening a FIFO does not wait for a writer; refused below.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as f:
            info = os.fstat(f.fileno())
            if not stat.S_ISREG(info.st_mode):
                raise error(str(path), "", "not a regular file")
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise error(str(path), "", f"cannot read: {exc.strerror or exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise error(str(path), "", f"larger than the {MAX_FILE_BYTES} bytes allowed")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(str(path), "", f"cannot read: not UTF-8 text ({exc.reason})") from None
    return text, read_toml(text, str(path), error)


def validate(
    model: type[Model],
    data: Any,
    source: str,
    error: type[ConfigError] = ConfigError,
    tags: tuple[str, ...] = (),
) -> Model:
    """Validate ``data`` as ``model``; every problem in one line.

    Parameters
    ----------
    model : type
        A pydantic model class.
    data : dict
        Nested dictionary as read from TOML.
    source : str
        Name of the data in error messages.
    error : type, default ConfigError
        The error to raise (a subclass of :class:`~crlbswarm.errors.ConfigError`).
    tags : tuple of str, optional
        The tags of the model's tagged unions, left out of the field paths.

    Returns
    -------
    model
        The validated instance.

    Raises
    ------
    ConfigError
        With the dotted path of the first offending field and every problem, ``"; "``-joined.
    """
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        problems = describe(exc, tags)
        field, first = problems[0]
        rest = [f"{f}: {r}" if f else r for f, r in problems[1:]]
        raise error(source, field, "; ".join([first, *rest])) from None


def describe(exc: ValidationError, tags: tuple[str, ...] = ()) -> list[tuple[str, str]]:
    """The problems of a pydantic error as ``(dotted field, reason)`` pairs.

    A validator that raises :class:`~crlbswarm.errors.FieldError` names its field itself
    (as a full dotted path); otherwise the field is pydantic's location of the error.

    Parameters
    ----------
    exc : pydantic.ValidationError
        The error.
    tags : tuple of str, optional
        Tags of tagged unions: pydantic inserts the tag after a list index
        (``obstacles.1.circle.radius``); the paths leave it out (``obstacles.1.radius``).

    Returns
    -------
    list of (str, str)
        One pair per problem, in pydantic's order.
    """
    out = []
    for err in exc.errors(include_url=False):
        cause = (err.get("ctx") or {}).get("error")
        if isinstance(cause, FieldError):
            out.append((cause.field, cause.reason))
            continue
        loc = [str(p) for p in err["loc"] if not str(p).startswith("function-")]
        # Drop the tag pydantic inserts after a list index of a tagged union (obstacles.1.circle).
        loc = [p for i, p in enumerate(loc) if not (i and loc[i - 1].isdigit() and p in tags)]
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "missing":
            msg = "missing required field"
        elif err["type"] == "extra_forbidden":
            msg = "unknown field"
        elif "input" in err and not isinstance(err["input"], dict | list):
            msg = f"{msg} (got {err['input']!r})"
        out.append((".".join(loc), msg))
    return out


def _parameters_section(model: type[BaseModel]) -> str:
    """The numpydoc ``Parameters`` section of a model, from its field declarations."""
    from pydantic_core import PydanticUndefined

    lines = ["    Parameters", "    ----------"]
    for name, info in model.model_fields.items():
        kind = _type_text(info.annotation)
        if info.default is not PydanticUndefined and not isinstance(info.default, BaseModel):
            kind += f", default {info.default!r}"
        elif not info.is_required():
            kind += ", optional"
        lines.append(f"    {name} : {kind}")
        description = info.description or ""
        for char in "\\*`|_":
            description = description.replace(char, "\\" + char)
        if re.match(r"[a-z]+[ ,]", description):  # a sentence, not a field or code name
            description = description[0].upper() + description[1:]
        text = description + ("" if description.endswith(".") else ".")
        lines += textwrap.wrap(text, 88, initial_indent=" " * 8, subsequent_indent=" " * 8)
    return "\n".join(lines) + "\n"


def _type_text(annotation: object) -> str:
    """A numpydoc type for a field annotation: ``list of float or None``."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return _type_text(args[0])
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_text(a) for a in args)
    if origin is typing.Literal:
        return "{" + ", ".join(repr(a) for a in args) + "}"
    if origin in (list, tuple) and args:
        return f"{origin.__name__} of {_type_text(args[0])}"
    if annotation is type(None):
        return "None"
    return getattr(annotation, "__name__", str(annotation))


def model_to_toml(model: BaseModel, header: str) -> str:
    """A model as a TOML document, each value commented with its field's description.

    Sub-models become tables, lists of sub-models arrays of tables; ``None`` values are
    left out (they mean "default").

    Parameters
    ----------
    model : pydantic.BaseModel
        The model.
    header : str
        A comment line at the top of the document.

    Returns
    -------
    str
        TOML text; validating it again gives an equal model.
    """
    import tomlkit

    # tomlkit builds an array one element at a time, re-indexing it at each append
    # (quadratic: 20 000 edges take half a minute); long arrays of numbers are written as
    # JSON text, which is valid TOML for them, in place of a placeholder string.
    long_arrays: dict[str, str] = {}

    def commented(value: Any, owner: BaseModel, key: str) -> Any:
        if _long_numeric_list(value):
            placeholder = f"@crlbswarm-array-{secrets.token_hex(16)}@"  # in no user text
            long_arrays[f'"{placeholder}"'] = json.dumps(value)
            value = placeholder
        item = tomlkit.item(value)
        description = type(owner).model_fields[key].description
        if description:
            item.comment(description)
        return item

    doc = tomlkit.document()
    doc.add(tomlkit.comment(header))
    for key, value in model.model_dump(exclude_none=True).items():
        sub = getattr(model, key)
        if isinstance(sub, BaseModel):
            table = tomlkit.table()
            for sub_key, sub_value in value.items():
                table.add(sub_key, commented(sub_value, sub, sub_key))
            doc.add(tomlkit.nl())
            doc.add(key, table)
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            array = tomlkit.aot()
            for item in value:
                array.append(tomlkit.item(item))
            doc.add(tomlkit.nl())
            doc.add(key, array)
        elif (
            value == []
            and type(model).model_fields[key].get_default(call_default_factory=True) == []
        ):
            continue  # an empty list that is also the default: written as nothing
        else:
            doc.add(key, commented(value, model, key))
    text = tomlkit.dumps(doc)
    for placeholder, json_array in long_arrays.items():
        if text.count(placeholder) != 1:  # pragma: no cover - a 128-bit token collided
            raise RuntimeError("model_to_toml: placeholder not unique")
        text = text.replace(placeholder, json_array)
    return text


#: Arrays longer than this are written without tomlkit (see :func:`model_to_toml`).
LONG_ARRAY = 64


def _long_numeric_list(value: Any) -> bool:
    """A list of more than :data:`LONG_ARRAY` finite numbers or lists of them."""

    def numeric(v: Any) -> bool:
        if isinstance(v, list):
            return all(numeric(x) for x in v)
        return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)

    return isinstance(value, list) and len(value) > LONG_ARRAY and numeric(value)
