"""The argparse types shared by both command lines: a clear usage error (exit 2) instead of a traceback or a
value no command can use."""

from __future__ import annotations

import argparse

import pytest

from dpcontrol.arguments import finite_number, positive_number


@pytest.mark.parametrize(("text", "value"), [("1.5", 1.5), ("1e-3", 1e-3), ("120", 120.0)])
def test_positive_numbers(text: str, value: float) -> None:
    assert positive_number(text) == value


@pytest.mark.parametrize(("text", "why"), [("0", "> 0"), ("-2", "> 0"), ("inf", "> 0"), ("nan", "> 0"),
                                           ("ten", "expected a number")])
def test_not_positive_numbers(text: str, why: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=why):
        positive_number(text)


@pytest.mark.parametrize(("text", "value"), [("-5", -5.0), ("0", 0.0), ("359.9", 359.9)])
def test_finite_numbers(text: str, value: float) -> None:
    assert finite_number(text) == value


@pytest.mark.parametrize(("text", "why"), [("inf", "finite"), ("-inf", "finite"), ("nan", "finite"),
                                           ("north", "expected a number")])
def test_not_finite_numbers(text: str, why: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=why):
        finite_number(text)
