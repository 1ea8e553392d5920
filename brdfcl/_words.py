"""Counted nouns in what brdfcl prints: ``count(1, "material")`` is "1 material", ``count(2,
"material")`` "2 materials"; ``noun`` the word alone ("unknown materials a, b")."""
from __future__ import annotations


def noun(n: int, word: str, plural: str | None = None) -> str:
    """``word``, or its plural (``plural``, else word + "s") unless ``n`` is 1."""
    return word if n == 1 else plural or word + "s"


def count(n: int, word: str, plural: str | None = None) -> str:
    """``n`` and its noun: "1 material", "2 materials"."""
    return f"{n} {noun(n, word, plural)}"
