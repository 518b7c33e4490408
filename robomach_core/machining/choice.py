"""What the cell can run, and the one rule that chooses a configuration (CLI, REST and GUIs).

PROBLEM   A configuration is only worth choosing if the cell can run it and the exported program
          carries it: CMRR needs a feed override driven by the force in the controller (ABB's
          FC SpeedChange, or the UR's force mode), online compensation an interface that
          corrects the path while it runs; offline compensation and a constant feed need
          nothing but the program. A table that recommends online compensation to a cell
          without the option promises an error the cell will never see.
STRATEGY  The cell states its options (``CellCapabilities``); the defaults follow the program
          language of the arm's controller (an ABB cell with RAPID has FC SpeedChange and no
          path-correction option; a UR with URScript has force mode), through a mapping owned
          here, so a new language gets the safe default (no option) until it is listed. Each
          configuration needs a set of requirements (``requirements``), each met by any of a
          set of options. ``choose`` picks among the runnable rows only, and says why.
SOLUTION  ``choose(rows, capabilities)`` -> ``Choice(index, reason)``; the rule: among the
          completed runs the cell can run whose peak force stays within the limit, those
          within 5 % of the fastest cycle; of these the smallest finished-wall max error; none
          when no run keeps the limit (the reason says which came closest). With variations
          the same rule reads the 95th percentiles (the nominal stock counted) and asks for
          every stock to complete. A row whose feed is a stage schedule planned offline
          (``machining.schedule``, only when the person sets ``stages`` "planned") needs no
          feed override: it runs on any cell, as the constant feed does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

# The choice: peak force within the limit (no margin above it: the limit is "the force the
# cut must not exceed"), cycle within this of the fastest.
PEAK_MARGIN = 0.0
CYCLE_MARGIN = 0.05
# A configuration must complete on at least this share of the stocks of a variation sweep.
COMPLETED_SHARE = 1.0

OPTION_NAMES: tuple[str, ...] = ("fc_speed_change", "path_correction", "force_mode")
OPTION_TEXT = {
    "fc_speed_change": "FC SpeedChange (ABB Force Control option)",
    "path_correction": "an online path-correction interface",
    "force_mode": "the UR's force/torque sensing (e-Series: the program runs its own feed loop)",
}
# Option -> the arm families whose controllers have it: FC SpeedChange is ABB's (RobotWare
# Force Control), the UR's built-in F/T sensor with force mode is the UR's; an online path
# correction exists on all three (ABB Path Offset / CorrWrite, UR path_offset, KUKA RSI).
OPTION_FAMILIES: dict[str, tuple[str, ...]] = {
    "fc_speed_change": ("abb",),
    "force_mode": ("ur",),
    "path_correction": ("abb", "ur", "kuka"),
}
FAMILY_TEXT = {"abb": "ABB (RAPID)", "ur": "UR (URScript)", "kuka": "KUKA (KRL)"}
# Requirement -> the options that meet it (any one).
REQUIREMENTS: dict[str, tuple[str, ...]] = {
    "feed_override": ("fc_speed_change", "force_mode"),
    "online_correction": ("path_correction",),
}
REQUIREMENT_TEXT = {
    "feed_override": "a force-driven feed override (ABB: FC SpeedChange; UR: the program's "
    "own feed loop on its force/torque sensor)",
    "online_correction": "an online path-correction interface",
}
# What a family's controller cannot be given by robomach, said where a row needs it.
FAMILY_LACKS_TEXT: dict[tuple[str | None, str], str] = {
    ("kuka", "feed_override"): "a force-driven feed override: robomach writes none for a KUKA "
    "controller (KRL has no force-driven override without KUKA.ForceTorqueControl or an RSI "
    "loop, which robomach does not generate), so only the constant feed runs there",
}
# Program language -> the options such a cell has by default (a language not listed: none).
LANGUAGE_DEFAULT_OPTIONS: dict[str, tuple[str, ...]] = {
    "rapid": ("fc_speed_change",),
    "urscript": ("force_mode",),
    "krl": (),
}


LANGUAGE_FAMILY = {"rapid": "abb", "urscript": "ur", "krl": "kuka"}


def options_for_family(family: str | None) -> tuple[str, ...]:
    """The options an arm family's controller can have (every option for an unknown one)."""
    if family is None:
        return OPTION_NAMES
    return tuple(o for o in OPTION_NAMES if family in OPTION_FAMILIES[o])


def check_options_for_arm(options, family: str | None, arm: str) -> None:
    """Raise ``MachiningSettingsError`` naming the options an arm's controller cannot have."""
    foreign = [o for o in OPTION_NAMES if o in set(options) and o not in options_for_family(family)]
    if foreign:
        from .errors import MachiningSettingsError

        owners = "; ".join(
            f"{o} is for {', '.join(FAMILY_TEXT.get(f, f) for f in OPTION_FAMILIES[o])} controllers"
            for o in foreign
        )
        offered = ", ".join(options_for_family(family)) or "none"
        raise MachiningSettingsError(
            f"the {arm} arm's controller ({FAMILY_TEXT.get(family or '', family)}) cannot have "
            f"{', '.join(foreign)}: {owners}; its options: {offered}"
        )


@dataclass(frozen=True)
class CellCapabilities:
    """The controller options of the cell (``OPTION_NAMES``) and its arm family (None: any)."""

    options: frozenset[str] = frozenset()
    family: str | None = None

    def __post_init__(self) -> None:
        unknown = sorted(set(self.options) - set(OPTION_NAMES))
        if unknown:
            from .errors import MachiningSettingsError

            raise MachiningSettingsError(
                f"unknown cell option(s) {', '.join(unknown)}; choose from "
                f"{', '.join(OPTION_NAMES)}"
            )
        object.__setattr__(self, "options", frozenset(self.options))

    @classmethod
    def for_language(cls, language: str) -> CellCapabilities:
        """The default options of a cell programmed in ``language``."""
        return cls(
            frozenset(LANGUAGE_DEFAULT_OPTIONS.get(language, ())), LANGUAGE_FAMILY.get(language)
        )

    @classmethod
    def for_family(cls, family: str | None, options) -> CellCapabilities:
        """The cell's ``options`` that its arm family's controller can have (others dropped:
        an arm changed since they were set)."""
        allowed = options_for_family(family)
        return cls(frozenset(o for o in options if o in allowed), family)

    def describe(self) -> str:
        if not self.options:
            return "no controller options"
        return ", ".join(OPTION_TEXT[o] for o in OPTION_NAMES if o in self.options)


def requirements(
    controller: str, compensation: str, feed: str | None = "controller"
) -> tuple[str, ...]:
    """What a configuration needs from the cell beyond running the program; ``feed``
    ``"program"`` (a stage schedule planned offline, ``machining.schedule``): its feeds are
    the program's speeds, and it needs no feed override."""
    out = []
    if controller != "constant" and feed != "program":
        out.append("feed_override")
    if compensation == "online":
        out.append("online_correction")
    return tuple(out)


def missing(
    controller: str,
    compensation: str,
    capabilities: CellCapabilities,
    feed: str | None = "controller",
) -> tuple[str, ...]:
    """The requirements of a configuration the cell does not meet."""
    return tuple(
        r
        for r in requirements(controller, compensation, feed)
        if not any(o in capabilities.options for o in REQUIREMENTS[r])
    )


def needs_text(requirement: str, capabilities: CellCapabilities) -> str:
    """What a configuration needs and the cell lacks, in words (the family's reason when its
    controller cannot be given it)."""
    return FAMILY_LACKS_TEXT.get((capabilities.family, requirement), REQUIREMENT_TEXT[requirement])


def mark_runnable(
    rows: list[dict[str, Any]], capabilities: CellCapabilities
) -> list[dict[str, Any]]:
    """The rows with ``runnable`` and ``needs`` (what the cell lacks, in words) set."""
    out = []
    for row in rows:
        lacks = missing(row["controller"], row["compensation"], capabilities, row.get("feed"))
        out.append(
            dict(
                row,
                runnable=not lacks,
                needs=[needs_text(r, capabilities) for r in lacks] or None,
            )
        )
    return out


@dataclass(frozen=True)
class Choice:
    """The rule's pick: ``index`` into the rows (None: nothing can be chosen) and why."""

    index: int | None
    reason: str


def _figures(row: dict[str, Any]) -> tuple[Any, Any, Any, bool]:
    """(cycle, peak, wall error, completed) as the rule reads them: the 95th percentiles of a
    variation sweep, else the single run's."""
    if "cycle_time_p95_s" in row:
        complete = row.get("completed_share", 0.0) >= COMPLETED_SHARE
        return (
            row["cycle_time_p95_s"],
            row["force_peak_p95_N"],
            row["wall_error_max_p95_mm"],
            complete,
        )
    return (
        row.get("cycle_time_s"),
        row.get("force_peak_N"),
        row.get("wall_error_max_mm"),
        bool(row.get("completed")),
    )


def choose(rows: list[dict[str, Any]], capabilities: CellCapabilities) -> Choice:
    """The configuration to choose (module docstring), with the rule's reason in words."""
    p95 = bool(rows) and "cycle_time_p95_s" in rows[0]
    tag = " (95th percentiles over the stocks)" if p95 else ""
    runnable = [
        i
        for i, r in enumerate(rows)
        if not missing(r["controller"], r["compensation"], capabilities, r.get("feed"))
    ]
    not_here = len(rows) - len(runnable)
    done = [i for i in runnable if _figures(rows[i])[3] and _figures(rows[i])[0] is not None]
    if not done:
        why = "none of the configurations this cell can run completed"
        if not runnable:
            why = f"this cell ({capabilities.describe()}) can run none of the configurations"
        return Choice(None, why)
    safe = [i for i in done if within_limit(_figures(rows[i])[1], rows[i]["force_limit_N"])]
    if not safe:
        low = min(done, key=lambda i: _figures(rows[i])[1])
        row = rows[low]
        return Choice(
            None,
            f"none of the {len(done)} completed configurations this cell can run keeps the "
            f"peak force{tag} within the {row['force_limit_N']:g} N limit (the lowest: "
            f"{_figures(row)[1]:.1f} N, {row['controller']} / {row['compensation']}); raise "
            "the limit, or lower the CMRR reference force (0.7 of the limit by default)",
        )
    fastest = min(_figures(rows[i])[0] for i in safe)
    quick = [i for i in safe if _figures(rows[i])[0] <= (1 + CYCLE_MARGIN) * fastest]
    pick = min(quick, key=lambda i: (_figures(rows[i])[2], _figures(rows[i])[0]))
    cycle, peak, wall, _ = _figures(rows[pick])
    row = rows[pick]
    parts = [
        f"{row['controller']} / {row['compensation']}{tag}: of the {len(done)} completed "
        f"configurations this cell can run ({capabilities.describe()})",
        f"{len(safe)} keep the peak force within the {row['force_limit_N']:g} N limit",
        f"{len(quick)} are within 5 % of the fastest cycle ({fastest:.1f} s), and this one "
        f"leaves the smallest wall error ({wall:.3f} mm; cycle {cycle:.1f} s, peak {peak:.1f} N)",
    ]
    if not_here:
        parts.append(f"{not_here} configurations need options this cell lacks")
    return Choice(pick, "; ".join(parts) + ".")


def within_limit(peak_N: float | None, limit_N: float) -> bool:
    """The force limit as documented: the peak force may reach it, not pass it."""
    return peak_N is not None and peak_N <= (1.0 + PEAK_MARGIN) * limit_N


RULE_TEXT = (
    "among the completed configurations the cell can run, those whose peak force stays within "
    "the force limit; of those within 5 % of the fastest cycle, the smallest wall max error "
    "(with variations: the 95th percentiles over the nominal stock and the drawn ones, every "
    "stock completed)"
)
