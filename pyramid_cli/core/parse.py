"""Text to :mod:`expr` trees: the paper's Unicode notation and an ASCII spelling.

Grammar (chains are right-associative, ``A ⊗↓ B`` means ``A ⊗↓ (B ⊗ g)``)::

    chain    := operand [OP chain]
    operand  := primary [POWER]
    primary  := 'g' | filter | literal | '(' chain ')'
    filter   := ['h_'] NAME [variant]          variant: ^↘ ^{4×4} ⁴ˣ⁴ \\ ^nw ...
    literal  := [INT '/' INT] '[' row (';' row)* ']' ['/' INT]
    OP       := ⊗ | ⊗↓ [STRIDE] | ⊗↑ | * | *v [STRIDE] | *^ | (x) | (x)v | (x)^
    POWER    := '^' INT | '^{' INT '}' | superscript digits
    STRIDE   := POWER (only after ⊗↓: one step of stride 2^m)

Every failure is an :class:`~pyramid_cli.core.errors.ExpressionError` that points
at the offending column; no other exception escapes :func:`parse`.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from fractions import Fraction
from typing import NoReturn

from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import ExpressionError, UsageError
from pyramid_cli.core.expr import Apply, Expr, Filter, Input, Literal, Named, Op, steps

MAX_POWER = 16
MAX_DIGITS = 12  # digits of a number in a written mask (weights stay exact and fit a float)

_SUPDIGITS = "⁰¹²³⁴⁵⁶⁷⁸⁹"
_ARROW_SE = {"↘", "\\", "se", "dr"}
_ARROW_NW = {"↖", "↙", "nw", "ul"}  # the paper prints box↖ as ↙ (docs/design.md §2)

_ALIASES = catalogue.ALIASES
_NAME_OF = {alias: key for key, names in _ALIASES.items() for alias in names}
_KNOWN = sorted({n for names in _ALIASES.values() for n in names} | {"gauss5", "gauss7", "doo-sabin",
                                                                      "four-point"})
_MASK_ONLY = catalogue.MASK_ONLY
_SYNTH_ONLY = catalogue.SYNTHESIS_ONLY


@dataclass
class Token:
    kind: str     # NAME OP LPAR RPAR POW VARIANT LBRACK RBRACK SEMI NUM SLASH COMMA END
    text: str
    pos: int
    value: object = None


_TOKEN_RE = re.compile(
    r"""
    (?P<ws>\s+)
  | (?P<op>⊗\s*(_\s*\{?\s*)?[↓↑]\s*\}?|⊗\s*[v^]|\(x\)[v^]?|⊗|\*[v^]?|[⊛∗])
  | (?P<pow>\^\s*\{\s*-?\d+\s*\}|\^\s*-?\d+(?![×xX\d])|[⁰¹²³⁴⁵⁶⁷⁸⁹]+(?![ˣ]))
  | (?P<variant>\^\s*\{[^}]*\}|\^\s*(\d+\s*[×xX]\s*\d+|[↘↖↙\\]|[A-Za-z]+)|[⁰¹²³⁴⁵⁶⁷⁸⁹]+ˣ[⁰¹²³⁴⁵⁶⁷⁸⁹]+|[↘↖↙\\])
  | (?P<name>[A-Za-z][A-Za-z0-9_\-]*)
  | (?P<num>\d+)
  | (?P<lpar>\()
  | (?P<rpar>\))
  | (?P<lbrack>\[)
  | (?P<rbrack>\])
  | (?P<semi>;)
  | (?P<slash>/)
  | (?P<comma>,)
  | (?P<minus>[-−])
    """,
    re.VERBOSE,
)


def _sup_to_int(s: str) -> int:
    return int("".join(str(_SUPDIGITS.index(ch)) for ch in s))


def tokenize(text: str) -> list[Token]:
    tokens: list[Token] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN_RE.match(text, pos)
        if not m:
            ch = text[pos]
            raise ExpressionError(f"unexpected character {ch!r}", text, pos)
        kind = m.lastgroup
        assert kind is not None, "every alternative of _TOKEN_RE is a named group"
        tok = m.group()
        if kind != "ws":
            tokens.append(Token(kind.upper(), tok, pos))
        pos = m.end()
    tokens.append(Token("END", "", len(text)))
    return tokens


def _op_of(tok: Token) -> Op:
    t = tok.text
    if "↓" in t or t.endswith("v"):
        return Op.DOWN
    if "↑" in t or t.endswith("^"):
        return Op.UP
    return Op.CONV


def _int_of_pow(tok: Token, text: str) -> int:
    t = tok.text
    digits = t if t[0] in _SUPDIGITS else re.sub(r"[\^{}\s-]", "", t)
    if len(digits.lstrip("0⁰")) > 3:  # far out of range, and int() of thousands of digits is refused
        raise ExpressionError(f"exponent must be between 1 and {MAX_POWER}", text, tok.pos, len(t))
    if t[0] in _SUPDIGITS:
        n = _sup_to_int(t)
    else:
        n = int(re.sub(r"[\^{}\s]", "", t))
    if not 1 <= n <= MAX_POWER:
        raise ExpressionError(f"exponent must be between 1 and {MAX_POWER}, not {n}", text, tok.pos, len(t))
    return n


@dataclass
class _Operand:
    """A parsed operand: a filter (possibly powered), ``g``, or a parenthesised chain."""

    filter: Filter | None = None
    power: int = 1
    image: Expr | None = None
    span: tuple[int, int] = (0, 0)


class _Parser:
    def __init__(self, text: str):
        self.text = text
        self.tokens = tokenize(text)
        self.i = 0

    def peek(self) -> Token:
        return self.tokens[self.i]

    def take(self) -> Token:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def fail(self, message: str, tok: Token | None = None, length: int | None = None) -> NoReturn:
        tok = tok or self.peek()
        raise ExpressionError(message, self.text, tok.pos, length or max(1, len(tok.text)))

    # chain := operand [OP chain]
    def chain(self, depth: int = 0) -> Expr:
        if depth > 200:
            self.fail("expression nested too deeply")
        left = self.operand(depth)
        tok = self.peek()
        if tok.kind != "OP":
            return self._as_image(left, Op.CONV)
        self.take()
        op = _op_of(tok)
        stride = 1
        if self.peek().kind == "POW":
            ptok = self.take()
            if op is not Op.DOWN:
                self.fail(f"only ⊗↓ takes a stride exponent (⊗↓ᵐ), not {op.unicode}", ptok)
            stride = _int_of_pow(ptok, self.text)
        if left.filter is None:
            what = "the image g" if isinstance(left.image, Input) else "an image expression"
            raise ExpressionError(f"a filter must stand left of {op.unicode}, not {what}", self.text,
                                  left.span[0], left.span[1] - left.span[0])
        if self.peek().kind in ("END", "RPAR", "OP"):
            self.fail(f"expected a filter or g after {op.unicode}")
        right = self.chain(depth + 1)
        self._check_op(left.filter, op)
        return Apply(op, left.filter, right, left.power, stride, left.span)

    def _check_op(self, f: Filter, op: Op) -> None:
        start, end = f.span
        if isinstance(f, Literal):
            if op is Op.UP:
                raise ExpressionError("a written mask has one phase; ⊗↑ needs a synthesis filter with four "
                                      "phase masks (nearest, midpoint, doosabin, cubic, fourpoint)",
                                      self.text, start, end - start)
            return
        key = f.key
        if op is Op.UP and (key in _MASK_ONLY or key.startswith("gauss")):
            raise ExpressionError(f"{key!r} is a single mask for ⊗ and ⊗↓; ⊗↑ needs a synthesis filter "
                                  "(nearest, midpoint, doosabin, cubic, fourpoint)", self.text, start, end - start)
        if op is not Op.UP and key in _SYNTH_ONLY:
            raise ExpressionError(f"{key!r} is a synthesis filter (four phase masks): use it with ⊗↑, "
                                  f"not {op.unicode}", self.text, start, end - start)

    def _as_image(self, operand: _Operand, op: Op) -> Expr:
        """A chain's last operand is the image: ``g``, ``(chain)``, or ``F`` meaning ``F ⊗ g``."""
        if operand.image is not None:
            return operand.image
        f = operand.filter
        assert f is not None, "an operand is a filter or an image"
        if self.i and self._is_whole(operand):
            op = self._natural_op(f)
        self._check_op(f, op)
        return Apply(op, f, Input(), operand.power, 1, operand.span)

    def _is_whole(self, operand: _Operand) -> bool:
        return operand.span == (self.tokens[0].pos, self.tokens[-2].pos + len(self.tokens[-2].text))

    def _natural_op(self, f: Filter) -> Op:
        """A lone filter runs with its own operator: basic ⊗, analysis ⊗↓, synthesis ⊗↑."""
        if isinstance(f, Literal):
            return Op.CONV
        if f.key == "cubic":
            raise ExpressionError("'cubic' alone is ambiguous: write 'cubic ⊗↓ g' (analysis) or "
                                  "'cubic ⊗↑ g' (synthesis)", self.text, f.span[0], f.span[1] - f.span[0])
        if f.key in _SYNTH_ONLY:
            return Op.UP
        if f.key in catalogue.NATURAL_DOWN:
            return Op.DOWN
        return Op.CONV

    # operand := primary [POWER]
    def operand(self, depth: int) -> _Operand:
        start_tok = self.peek()
        result = self.primary(depth)
        if self.peek().kind == "POW":
            ptok = self.take()
            if result.filter is None:
                self.fail("a power (h)ᵐ applies to a filter, not to an image", ptok)
            result.power = _int_of_pow(ptok, self.text)
            last = self.tokens[self.i - 1]
            result.span = (start_tok.pos, last.pos + len(last.text))
        return result

    def primary(self, depth: int) -> _Operand:
        tok = self.peek()
        if tok.kind == "LPAR":
            self.take()
            inner_start = self.i
            if self.peek().kind == "RPAR":
                self.fail("empty parentheses")
            if self.peek().kind in ("NAME", "LBRACK", "NUM"):
                width = self._filter_width(inner_start)
                if self.tokens[inner_start + width].kind == "RPAR":
                    # "(h)" around a single filter stays a filter: (h_box^{4×4})^2 ⊗↓ g
                    inner = self.named() if self.peek().kind == "NAME" else self.literal()
                    close = self.take()
                    if inner.filter is not None:
                        return _Operand(filter=inner.filter, span=(tok.pos, close.pos + 1))
                    return _Operand(image=inner.image, span=(tok.pos, close.pos + 1))
            expr = self.chain(depth + 1)
            close = self.peek()
            if close.kind != "RPAR":
                self.fail("expected ')'" if close.kind != "END" else f"'(' at column {tok.pos + 1} is never closed",
                          close)
            self.take()
            span = (tok.pos, close.pos + 1)
            return _Operand(image=expr, span=span)
        if tok.kind == "NAME":
            return self.named()
        if tok.kind in ("LBRACK", "NUM"):
            return self.literal()
        if tok.kind == "END":
            self.fail("expected a filter name or g" if self.text.strip() else "empty expression")
        if tok.kind == "RPAR":
            self.fail("unmatched ')'")
        if tok.kind == "OP":
            self.fail(f"expected a filter before {_op_of(tok).unicode}")
        self.fail(f"unexpected {tok.text!r}")

    def _filter_width(self, start: int) -> int:
        """How many tokens a lone filter starting at token ``start`` spans."""
        j = start
        if self.tokens[j].kind == "NAME":
            j += 1
            while self.tokens[j].kind == "VARIANT":
                j += 1
            return j - start
        depth = 0
        while True:
            k = self.tokens[j].kind
            if k == "END":
                return j - start
            depth += k == "LBRACK"
            depth -= k == "RBRACK"
            j += 1
            if depth == 0 and k == "RBRACK":
                if self.tokens[j].kind == "SLASH" and self.tokens[j + 1].kind == "NUM":
                    j += 2
                return j - start

    def named(self) -> _Operand:
        tok = self.take()
        raw = tok.text
        name = raw[2:] if raw[:2].lower() == "h_" else raw
        end = tok.pos + len(raw)
        variants = []
        while self.peek().kind == "VARIANT":
            v = self.take()
            variants.append(v)
            end = v.pos + len(v.text)
        span = (tok.pos, end)
        if name.lower() == "g" and not variants:
            return _Operand(image=Input(span), span=span)
        if name.lower() == "h" and raw.lower() == "h":
            self.fail("'h' is a placeholder: write a filter name such as box, bartlett, quadratic or doosabin", tok)
        key = self._resolve(name, variants, tok, span)
        return _Operand(filter=Named(key, span), span=span)

    def _resolve(self, name: str, variants: list[Token], tok: Token, span) -> str:
        norm = name.lower().replace("-", "").replace("_", "")
        m = re.fullmatch(r"gauss(?:ian)?(\d+)(?:x\d+)?", norm)
        key = f"gauss{m.group(1)}" if m else _NAME_OF.get(norm)
        if key is None:
            close = difflib.get_close_matches(name.lower(), _KNOWN, n=1, cutoff=0.6)
            hint = f" (did you mean '{close[0]}'?)" if close else f"; known: {', '.join(sorted(_ALIASES))}"
            self.fail(f"unknown filter '{name}'{hint}", tok)
        for v in variants:
            key = self._apply_variant(key, v)
        if key == "gauss":
            raise ExpressionError("h_Gauss needs a size: gauss5, gauss7 or h_Gauss^{5×5}", self.text,
                                  span[0], span[1] - span[0])
        if key.startswith("gauss"):
            if len(key[5:].lstrip("0")) > 3:
                raise ExpressionError("Gaussian sizes are odd, 3 to 65", self.text, span[0], span[1] - span[0])
            n = int(key[5:])
            if n < 3 or n % 2 == 0 or n > 65:
                raise ExpressionError(f"Gaussian sizes are odd, 3 to 65, not {n}", self.text,
                                      span[0], span[1] - span[0])
        return key

    def _apply_variant(self, key: str, v: Token) -> str:
        body = v.text.lstrip("^").strip().strip("{}").strip()
        if body and body[0] in _SUPDIGITS:
            a, b = body.split("ˣ")
            body = f"{_sup_to_int(a)}x{_sup_to_int(b)}"
        low = body.lower().replace("×", "x").replace(" ", "")
        if low in _ARROW_SE or low in _ARROW_NW:
            if key not in ("box", "box_nw"):
                self.fail(f"only h_box takes an arrow (↘ or ↖), not '{key}'", v)
            return "box" if low in _ARROW_SE else "box_nw"
        sizes = catalogue.SIZE_VARIANTS
        m = re.fullmatch(r"(\d+)x(\d+)", low)
        if m and key == "gauss" and m.group(1) == m.group(2):
            return f"gauss{m.group(1)}"
        if m and key.startswith("gauss") and low == f"{key[5:]}x{key[5:]}":
            return key
        if m and low in sizes.get(key, {}):
            return sizes[key][low]
        if m:
            known = ", ".join(sizes.get(key, {})) or "none"
            self.fail(f"'{key}' has no size {low.replace('x', '×')} (sizes: {known.replace('x', '×')})", v)
        self.fail(f"unknown superscript '{body}' (expected an arrow ↘/↖ or a size such as 4×4)", v)

    # literal := [INT '/' INT] '[' rows ']' ['/' INT]
    def literal(self) -> _Operand:
        start = self.peek()
        scale = Fraction(1)
        if start.kind == "NUM":
            scale = self._fraction()
        if self.peek().kind != "LBRACK":
            self.fail("expected '[' to start a mask, e.g. 1/4 [1 1; 1 1]")
        self.take()
        rows: list[list[Fraction]] = [[]]
        while True:
            tok = self.peek()
            if tok.kind == "RBRACK":
                self.take()
                break
            if tok.kind == "SEMI":
                self.take()
                rows.append([])
            elif tok.kind == "COMMA":
                self.take()
            elif tok.kind in ("NUM", "MINUS"):
                rows[-1].append(self._signed_fraction())
            else:
                self.fail("expected a number, ';' or ']' in the mask" if tok.kind != "END" else "mask never closed")
        if self.peek().kind == "SLASH":
            self.take()
            den = self.peek()
            if den.kind == "NUM":
                self._check_digits(den)
            if den.kind != "NUM" or int(den.text) == 0:
                self.fail("expected a non-zero integer after '/'")
            self.take()
            scale /= int(den.text)
        end_tok = self.tokens[self.i - 1]
        span = (start.pos, end_tok.pos + len(end_tok.text))
        if any(len(r) != len(rows[0]) for r in rows) or not rows[0]:
            raise ExpressionError("mask rows must be non-empty and of equal length", self.text, span[0],
                                  span[1] - span[0])
        if len(rows) > 64 or len(rows[0]) > 64:
            raise ExpressionError("masks are limited to 64×64", self.text, span[0], span[1] - span[0])
        mask = tuple(tuple(v * scale for v in r) for r in rows)
        return _Operand(filter=Literal(mask, span), span=span)

    def _check_digits(self, tok: Token) -> None:
        if len(tok.text.lstrip("0")) > MAX_DIGITS:
            self.fail(f"a number in a mask has at most {MAX_DIGITS} digits, not {len(tok.text.lstrip('0'))}", tok)

    def _fraction(self) -> Fraction:
        self._check_digits(self.peek())
        num = Fraction(int(self.take().text))
        if self.peek().kind == "SLASH" and self.tokens[self.i + 1].kind == "NUM":
            self.take()
            self._check_digits(self.peek())
            den = self.take()
            if int(den.text) == 0:
                self.fail("division by zero", den)
            num /= int(den.text)
        return num

    def _signed_fraction(self) -> Fraction:
        sign = 1
        if self.peek().kind == "MINUS":
            self.take()
            sign = -1
        if self.peek().kind != "NUM":
            self.fail("expected a number")
        return sign * self._fraction()


def parse(text: str) -> Expr:
    """Parse a filter expression; raises :class:`ExpressionError` with a caret."""
    if len(text) > 10_000:
        raise ExpressionError("expression longer than 10000 characters", text[:40], 0)
    try:
        p = _Parser(text)
        expr = p.chain()
        if p.peek().kind != "END":
            tok = p.peek()
            p.fail("unmatched ')'" if tok.kind == "RPAR" else f"unexpected {tok.text!r} after a complete expression")
        return expr
    except RecursionError:
        raise ExpressionError("expression nested too deeply", text, 0) from None


def one_step(text: str, op: Op) -> Expr:
    """A pyramid role's filter: a filter name (applied with ``op``) or an expression that uses only ``op``.

    ``one_step("box4", Op.DOWN)`` is ``box4 ⊗↓ g``; ``"box *v^2 g"`` is taken as written. Raises
    :class:`~pyramid_cli.core.errors.UsageError` (exit 2) for an expression with another operator.
    """
    expr = parse(text) if any(ch in text for ch in "⊗*(") else parse(f"{text} {op.ascii} g")
    st = steps(expr)
    if not st or any(o is not op for o, _, _ in st):
        raise UsageError(f"'{text}' must use only {op.unicode} for this role")
    return expr
