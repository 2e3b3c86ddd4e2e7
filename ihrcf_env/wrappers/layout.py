"""Flat observation layouts (:mod:`ihrcf_env.core.layout`, re-exported here for the wrappers)."""

from __future__ import annotations

from ihrcf_env.core.layout import Block, Field, Layout, build_layout, layout_table

__all__ = [
    "Block",
    "Field",
    "Layout",
    "build_layout",
    "layout_table",
]
