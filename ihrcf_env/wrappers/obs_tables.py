"""The observation tables of ``docs/observations.md``, generated from the layout code (one source).

Each flat observation's table (:func:`~ihrcf_env.wrappers.layout.layout_table`) is made from the
same :class:`~ihrcf_env.wrappers.layout.Field` lists the wrappers build their observation from, for
the id's default options. In the page, a table sits between ``<!-- layout:KEY -->`` and
``<!-- /layout:KEY -->``; :func:`render` rewrites every such region. Run
``python -m ihrcf_env.wrappers.obs_tables`` to print the tables, or with ``--write PAGE`` to
update the page in place (``tests/test_docs.py`` checks the page equals its rendering).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS
from ihrcf_env.core.forecast import ForecastOptions
from ihrcf_env.wrappers.estimates import GROUND_TRUTH, hover_blocks
from ihrcf_env.wrappers.forecast_feed import FORECAST, forecast_fields
from ihrcf_env.wrappers.landing_obs import MOTION, MOTION_FIELDS, TRUTH_FIELDS, landing_blocks
from ihrcf_env.wrappers.layout import Block, build_layout, layout_table

__all__ = ["LANDING_IDS", "TABLES", "main", "render", "tables"]


#: The ids whose observation is the landing layout (:func:`landing_blocks`).
LANDING_IDS: tuple[str, ...] = ("ihrcf_env/DeckLanding-v1", "ihrcf_env/DeckLanding-v2")


def _landing() -> str:
    blocks = landing_blocks(DEFAULT_ESTIMATORS)
    size = build_layout(blocks).size
    ids = " and ".join(f"`{i}`" for i in LANDING_IDS)
    return (
        f"{ids} with the default estimators ({', '.join(DEFAULT_ESTIMATORS)}): {size} values.\n\n"
        + layout_table(blocks)
    )


def _landing_options() -> str:
    """The optional blocks, appended in this order after the estimators' (here all on, the
    forecast with its default horizons)."""
    base = landing_blocks(DEFAULT_ESTIMATORS)
    horizons = len(ForecastOptions().horizons)
    blocks: list[Block] = [
        *base,
        (MOTION, MOTION_FIELDS),
        (FORECAST, forecast_fields(horizons)),
        (GROUND_TRUTH, TRUTH_FIELDS),
    ]
    rows = layout_table(blocks).splitlines()
    fields = sum(len(f) for _, f in base)
    return "\n".join([*rows[:2], *rows[2 + fields :]])


def _hover() -> str:
    blocks = hover_blocks(DEFAULT_ESTIMATORS)
    size = build_layout(blocks).size
    return (
        f"`ihrcf_env/DeckHover-v0` with `flatten=True` and its default estimators: {size} values.\n\n"
        + layout_table(blocks)
    )


#: Region key -> the function making its table.
TABLES: dict[str, Callable[[], str]] = {
    "landing": _landing,
    "landing-options": _landing_options,
    "hover-flat": _hover,
}
_REGION = re.compile(r"(<!-- layout:(?P<key>[\w-]+) -->\n)(?P<body>.*?)(<!-- /layout:(?P=key) -->)", re.S)


def tables() -> dict[str, str]:
    """Region key -> its Markdown table."""
    return {key: make() for key, make in TABLES.items()}


def render(page: str) -> str:
    """``page`` with every ``layout:KEY`` region replaced by the table of ``KEY`` (KeyError naming
    an unknown key)."""
    made = tables()

    def table(m: re.Match[str]) -> str:
        key = m.group("key")
        if key not in made:
            raise KeyError(f"layout region {key!r}: no such table; known: {sorted(made)}")
        return m.group(1) + made[key] + "\n" + m.group(4)

    return _REGION.sub(table, page)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the tables, or rewrite the regions of ``--write PAGE``."""
    parser = argparse.ArgumentParser(prog="python -m ihrcf_env.wrappers.obs_tables", description=__doc__)
    parser.add_argument("--write", metavar="PAGE", help="rewrite the layout regions of this Markdown page")
    args = parser.parse_args(argv)
    if args.write:
        path = Path(args.write)
        path.write_text(render(path.read_text()))
        return 0
    for key, text in tables().items():
        sys.stdout.write(f"<!-- layout:{key} -->\n{text}\n<!-- /layout:{key} -->\n\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
