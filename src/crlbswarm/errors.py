"""The exceptions of crlbswarm.

Every error a user can cause is a :class:`FieldError` (a :class:`ValueError`): it carries the
name of the offending argument or scenario field and the reason as data (``field`` and
``reason``), and its message is the one line ``"<field>: <reason>"``. The command line maps
``field`` to its option (``n_uavs`` to ``--uavs``) without reading the message.
"""

from __future__ import annotations

__all__ = [
    "CampaignError",
    "ConfigError",
    "FieldError",
    "ScenarioError",
    "SimulationDivergedError",
    "one_line",
]


#: Longest reason kept in an error message, characters: a value echoed in a reason is cut
#: (a megabyte-long list in a file must not become a megabyte-long error line).
MAX_REASON = 400


def one_line(text: str, limit: int = MAX_REASON) -> str:
    """``text`` on one line (each run of whitespace, line breaks too, becomes one space),
    cut to ``limit`` characters: the one place where crlbswarm shortens what it quotes.

    Parameters
    ----------
    text : str
        Any text.
    limit : int, default MAX_REASON
        Longest result.

    Returns
    -------
    str
        The text, with ``"... (N characters)"`` (or ``"..."`` when ``limit`` is short) at
        the end if it was cut.
    """
    flat = " ".join(str(text).split())
    if len(flat) <= limit:
        return flat
    suffix = f"... ({len(flat)} characters)"
    if len(suffix) > limit // 2:
        suffix = "..."
    return flat[: limit - len(suffix)] + suffix


class FieldError(ValueError):
    """An invalid argument or field; one line naming it and saying why.

    Parameters
    ----------
    field : str
        Name of the argument (``"altitude"``) or dotted path of the field
        (``"control.epsilon"``, ``"radar.tx_power"``).
    reason : str
        What is wrong, without the field name (``"must be > 0, got -1"``).

    Attributes
    ----------
    field : str
        As given.
    reason : str
        As given.
    """

    def __init__(self, field: str, reason: str) -> None:
        field, reason = one_line(field), one_line(reason)
        super().__init__(f"{field}: {reason}" if field else reason)
        self.field = field
        self.reason = reason

    def __reduce__(self) -> tuple[type, tuple[str, str]]:  # picklable (Dask workers)
        return (type(self), (self.field, self.reason))


class ConfigError(FieldError):
    """An invalid configuration file (scenario or campaign spec).

    The message is ``"<source>: <field>: <reason>"``, where ``source`` names the file or the
    built-in scenario; several problems are joined by ``"; "`` on the same line.

    Parameters
    ----------
    source : str
        The file name or a description of where the data came from.
    field : str
        Dotted path of the (first) offending field; empty if the whole document is wrong
        (for example invalid TOML).
    reason : str
        What is wrong (all problems, joined by ``"; "``).

    Attributes
    ----------
    source : str
        As given.
    """

    def __init__(self, source: str, field: str, reason: str) -> None:
        source, field, reason = one_line(source), one_line(field), one_line(reason)
        ValueError.__init__(self, ": ".join(p for p in (source, field, reason) if p))
        self.source = source
        self.field = field
        self.reason = reason

    def __reduce__(self) -> tuple[type, tuple[str, str, str]]:  # type: ignore[override]
        return (type(self), (self.source, self.field, self.reason))


class ScenarioError(ConfigError):
    """An invalid mission scenario (see :mod:`crlbswarm.scenario`)."""


class SimulationDivergedError(RuntimeError):
    """A run produced NaN or runaway positions; the message names the seed and the step."""


class CampaignError(RuntimeError):
    """A campaign task failed on a worker; the message names the variant and the seeds."""
