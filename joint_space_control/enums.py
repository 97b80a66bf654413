"""Enumerations read from node parameters: one ``parse`` for all of them.

A parameter value that names no member must be rejected with a message listing the allowed
values (it reaches the user as the reason of a refused parameter update or a node that does
not start). The lookup and the listing are written here once; each enumeration only words
its message, because the message is part of the nodes' observable behaviour.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Self


class ParsedEnum(StrEnum):
    """A ``StrEnum`` with :meth:`parse`; subclasses pass their error wording as
    ``class Mode(ParsedEnum, invalid="'mode' is {value!r}; allowed: {allowed}")``, where
    ``{value}`` is the rejected value and ``{allowed}`` the members' values, comma-separated.
    """

    def __init_subclass__(cls, invalid: str = "{value!r} is not one of: {allowed}", **kwargs):
        super().__init_subclass__(**kwargs)
        cls._invalid = invalid

    @classmethod
    def parse(cls, value: str) -> Self:
        """The member whose value is ``value``; ValueError (allowed values listed) if none."""
        try:
            return cls(value)
        except ValueError:
            allowed = ", ".join(m.value for m in cls)
            raise ValueError(cls._invalid.format(value=value, allowed=allowed)) from None
