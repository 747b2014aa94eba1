"""Doctest output compared as numbers, so that an example prints the same on every CPU.

Two CPUs (AVX-512 or not, OpenBLAS's SkylakeX or Haswell kernels, torch's vectorised loops)
may round the same computation differently in the last bits: ``1.0000000000000004`` for
``1.0``, ``-0.0`` for ``0.0``. :class:`NumberChecker` reads every decimal number in an
example's expected output to the precision it is written with: the printed number matches
when it rounds to the written one (within half a unit of the last written digit), and a zero
matches whatever its sign. Everything else (integers, words, ``...`` with ELLIPSIS) is
compared as doctest always does. It is the checker of every docstring example in the suite
(``tests/test_doctests.py``), and :func:`exact_floats` is the rule that keeps its precision
meaningful: an expected float written with more than :data:`MAX_DIGITS` significant digits
would be compared to the last bit, so the suite refuses it.

Examples
--------
>>> import doctest
>>> NumberChecker().check_output("[1.0, 0.0]\\n", "[1.0000000000000004, -0.0]\\n", 0)
True
>>> NumberChecker().check_output("0.33\\n", "0.3333333\\n", 0)
True
>>> NumberChecker().check_output("0.33\\n", "0.34\\n", 0)
False
>>> exact_floats("(2.0, 0.3333333333333333)")
['0.3333333333333333']
"""

import doctest
import re

__all__ = ["NumberChecker", "exact_floats", "MAX_DIGITS"]

MAX_DIGITS = 12
"""Significant digits an expected float may be written with; more would be compared exactly."""

# a decimal number with a point or an exponent (integers are compared as text, exactly); it may
# touch an ELLIPSIS ("0.33...") but not a word or another point ("v1.2", "1.5.3")
_ALONE_BEFORE = r"(?<!\w)(?<!(?<!\.\.)\.)"
_ALONE_AFTER = r"(?!\w)(?!\.(?!\.\.))"
_FLOAT = re.compile(
    _ALONE_BEFORE + r"[+-]?\d*\.(?P<frac>\d*)(?:[eE](?P<exp1>[+-]?\d+))?" + _ALONE_AFTER
    + "|" + _ALONE_BEFORE + r"[+-]?\d+[eE](?P<exp2>[+-]?\d+)" + _ALONE_AFTER
)
# numpy's room for a minus sign after an opening bracket ("[ 1., -0.]" beside "[1., 0.]")
_SIGN_ROOM = re.compile(r"(?<=[\[(]) +")
# a zero written as an integer: "-0" and "0" are the same number
_ZERO = re.compile(r"(?<![\w.])[+-]?0(?![\w.])")


def _floats(text: str) -> list[re.Match]:
    """The decimal numbers of ``text`` with a digit, in order."""
    return [m for m in _FLOAT.finditer(text) if any(ch.isdigit() for ch in m.group(0))]


def _half_unit(match: re.Match) -> float:
    """Half a unit of the last digit ``match`` is written with (``0.05`` for ``1.0``)."""
    fraction = match.group("frac") or ""
    exponent = int(match.group("exp1") or match.group("exp2") or 0)
    return 0.5 * 10.0 ** (exponent - len(fraction))


def _same_number(want: re.Match, got: re.Match) -> bool:
    """Whether ``got`` rounds to ``want`` at the precision ``want`` is written with."""
    w, g = float(want.group(0)), float(got.group(0))
    return abs(g - w) <= _half_unit(want) * (1.0 + 1e-9)


def _significant_digits(token: str) -> int:
    """Significant digits of a written decimal number (``0.0012`` has 2, ``1.50`` has 3)."""
    mantissa = re.split(r"[eE]", token.lstrip("+-"))[0].replace(".", "")
    return len(mantissa.lstrip("0")) or 1


def exact_floats(want: str) -> list[str]:
    """The floats of an expected output that :class:`NumberChecker` would compare exactly.

    Parameters
    ----------
    want : str
        An example's expected output.

    Returns
    -------
    list of str
        Each float written with more than :data:`MAX_DIGITS` significant digits (a full
        ``repr`` of a computed float), in order; empty when every float leaves room for the
        last bits to differ between CPUs.
    """
    return [m.group(0) for m in _floats(want) if _significant_digits(m.group(0)) > MAX_DIGITS]


def _rewrite(want: str, got: str) -> str:
    """``got`` with each number that matches ``want``'s at the same place written as in ``want``."""
    pieces, last = [], 0
    for w, g in zip(_floats(want), _floats(got), strict=False):
        if _same_number(w, g):
            pieces += [got[last:g.start()], w.group(0)]
            last = g.end()
    got = "".join(pieces) + got[last:]
    got = _ZERO.sub("0", got) if _ZERO.search(want) else got
    return got if _SIGN_ROOM.search(want) else _SIGN_ROOM.sub("", got)


class NumberChecker(doctest.OutputChecker):
    """doctest's checker with numbers compared to the precision they are written with.

    Used for every docstring example in the suite. A float in the expected output matches a
    printed one that rounds to it (``1.0`` matches ``1.0000000000000004``, ``0.33`` matches
    ``0.3333``); zeros match whatever their sign (``0.0`` and ``-0.0``, ``0`` and ``-0``, and
    numpy's room for a sign, ``[ 1., -0.]`` and ``[1., 0.]``); the rest of the text is
    compared by :class:`doctest.OutputChecker` with the example's option flags.
    """

    def check_output(self, want: str, got: str, optionflags: int) -> bool:  # noqa: D102
        if super().check_output(want, got, optionflags):
            return True
        return super().check_output(want, _rewrite(want, got), optionflags)
