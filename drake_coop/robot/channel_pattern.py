"""LCM channel patterns matched in linear time, for the tcpq hub (:mod:`~drake_coop.robot.tcpq_hub`).

An LCM client subscribes with a regular expression that must match the whole channel name
(LCM compiles ``^pattern$``; the Java ``TCPService`` hub uses ``Matcher.matches``). Compiled
with a backtracking engine (Python's ``re``) a client's pattern can take the hub down: 500
nested groups raise ``RecursionError`` in ``re.compile``, ``(a|a)*b`` on a long channel name
runs for hours. Here a pattern is parsed by a bounded parser into a Thompson automaton and
matched by simulating every state at once (Pike's method): time proportional to the
pattern's length times the channel's, whatever the pattern.

The syntax is the part of POSIX extended regular expressions LCM channels use in practice:
literal characters, a backslash followed by a punctuation character (that character,
literally), ``.``, bracket expressions ``[abc]``, ``[a-z0-9_]``, ``[^...]``, groups ``( )``, alternation ``|``, the
quantifiers ``*``, ``+``, ``?``, and ``^`` / ``$`` at the pattern's ends (implied anyway).
Anything else (``{m,n}``, a back-reference, an escaped letter such as backslash-d) is
refused with :class:`PatternError`, as are patterns longer than :data:`MAX_PATTERN` characters or nested
deeper than :data:`MAX_DEPTH` groups.
"""

from __future__ import annotations

__all__ = ["MAX_DEPTH", "MAX_PATTERN", "ChannelPattern", "PatternError"]

#: Longest pattern accepted (characters).
MAX_PATTERN = 256
#: Deepest nesting of groups accepted.
MAX_DEPTH = 16

# Instructions of the automaton: (op, a, b)
_CHAR, _SPLIT, _JMP, _MATCH = 0, 1, 2, 3
_SPECIAL = set("\\.[]()|*+?^${}")


class PatternError(ValueError):
    """A subscription pattern outside the accepted syntax or bounds (one line saying why)."""


class _Set:
    """A character test: one character, any character, or a bracket expression."""

    __slots__ = ("chars", "ranges", "negate", "any")

    def __init__(self, chars: str = "", ranges=(), negate: bool = False, any_: bool = False):
        self.chars, self.ranges, self.negate, self.any = frozenset(chars), tuple(ranges), \
            negate, any_

    def __call__(self, c: str) -> bool:
        if self.any:
            return True
        hit = c in self.chars or any(lo <= c <= hi for lo, hi in self.ranges)
        return hit != self.negate


class _Parser:
    """Recursive descent over the pattern into a tree: ``("set", _Set)``, ``("cat", [..])``,
    ``("alt", [..])``, ``("star"|"plus"|"opt", node)``, ``("empty",)``."""

    def __init__(self, text: str):
        self.text, self.i, self.depth = text, 0, 0

    def fail(self, what: str):
        raise PatternError(f"channel pattern {self.text[:60]!r}: {what} (at character "
                           f"{self.i})")

    def peek(self) -> str | None:
        return self.text[self.i] if self.i < len(self.text) else None

    def alternation(self):
        branches = [self.sequence()]
        while self.peek() == "|":
            self.i += 1
            branches.append(self.sequence())
        return branches[0] if len(branches) == 1 else ("alt", branches)

    def sequence(self):
        items = []
        while self.peek() not in (None, "|", ")"):
            atom = self.atom()
            while self.peek() in ("*", "+", "?"):
                op = {"*": "star", "+": "plus", "?": "opt"}[self.text[self.i]]
                self.i += 1
                if atom[0] in ("star", "plus", "opt"):
                    self.fail("a quantifier on a quantifier")
                atom = (op, atom)
            items.append(atom)
        return ("cat", items) if items else ("empty",)

    def atom(self):
        c = self.text[self.i]
        if c == "(":
            self.depth += 1
            if self.depth > MAX_DEPTH:
                self.fail(f"groups nested deeper than {MAX_DEPTH}")
            self.i += 1
            node = self.alternation()
            if self.peek() != ")":
                self.fail("an unclosed group")
            self.i += 1
            self.depth -= 1
            return node
        if c == "[":
            return ("set", self.bracket())
        self.i += 1
        if c == "\\":
            if self.i >= len(self.text):
                self.fail("a trailing backslash")
            c = self.text[self.i]
            self.i += 1
            if c.isalnum():
                self.fail(f"the escape \\{c} (only a punctuation character may be escaped)")
            return ("set", _Set(c))
        if c == ".":
            return ("set", _Set(any_=True))
        if c in "*+?":
            self.i -= 1
            self.fail(f"a quantifier {c!r} with nothing before it")
        if c in "{}":
            self.i -= 1
            self.fail("bounded repetition {m,n} is not supported")
        if c in "^$":
            self.i -= 1
            self.fail(f"{c!r} inside the pattern (allowed only at its ends)")
        if c == "]":
            self.i -= 1
            self.fail("an unopened bracket expression")
        return ("set", _Set(c))

    def bracket(self) -> _Set:
        self.i += 1                                     # past '['
        negate = self.peek() == "^"
        if negate:
            self.i += 1
        chars, ranges, first = [], [], True
        while True:
            c = self.peek()
            if c is None:
                self.fail("an unclosed bracket expression")
            if c == "]" and not first:
                self.i += 1
                return _Set("".join(chars), ranges, negate)
            if c == "[" and self.text[self.i + 1:self.i + 2] in (":", "=", "."):
                self.fail("character classes [: :] are not supported")
            first = False
            self.i += 1
            if self.peek() == "-" and self.text[self.i + 1:self.i + 2] not in ("]", ""):
                hi = self.text[self.i + 1]
                if hi < c:
                    self.fail(f"the range {c}-{hi} is reversed")
                ranges.append((c, hi))
                self.i += 2
            else:
                chars.append(c)


def _compile(node, code: list) -> None:
    """Append the instructions of ``node`` to ``code`` (Thompson's construction)."""
    kind = node[0]
    if kind == "set":
        code.append([_CHAR, node[1], None])
    elif kind == "empty":
        pass
    elif kind == "cat":
        for item in node[1]:
            _compile(item, code)
    elif kind == "alt":
        jumps = []
        for branch in node[1][:-1]:
            split = len(code)
            code.append([_SPLIT, split + 1, None])
            _compile(branch, code)
            jumps.append(len(code))
            code.append([_JMP, None, None])
            code[split][2] = len(code)
        _compile(node[1][-1], code)
        for j in jumps:
            code[j][1] = len(code)
    elif kind == "star":
        split = len(code)
        code.append([_SPLIT, split + 1, None])
        _compile(node[1], code)
        code.append([_JMP, split, None])
        code[split][2] = len(code)
    elif kind == "plus":
        start = len(code)
        _compile(node[1], code)
        code.append([_SPLIT, start, len(code) + 1])
    elif kind == "opt":
        split = len(code)
        code.append([_SPLIT, split + 1, None])
        _compile(node[1], code)
        code[split][2] = len(code)


class ChannelPattern:
    """One subscription's pattern, checked and compiled once; :meth:`fullmatch` of a channel
    name in time proportional to ``len(pattern) × len(channel)``.

    Parameters
    ----------
    text : str
        The pattern as the client sent it (at most :data:`MAX_PATTERN` characters).

    Raises
    ------
    PatternError
        Outside the syntax the module describes, longer than :data:`MAX_PATTERN`, or nested
        deeper than :data:`MAX_DEPTH`.
    """

    def __init__(self, text: str):
        if not isinstance(text, str):
            raise PatternError(f"channel pattern: a text is required, got {type(text).__name__}")
        if len(text) > MAX_PATTERN:
            raise PatternError(f"channel pattern of {len(text)} characters: at most "
                               f"{MAX_PATTERN}")
        self.text = text
        body = text[1:] if text.startswith("^") else text
        if body.endswith("$") and not body.endswith("\\$"):
            body = body[:-1]
        self.literal = body if not (_SPECIAL & set(body)) else None
        self._code: list = []
        if self.literal is None:
            parser = _Parser(body)
            tree = parser.alternation()
            if parser.i != len(body):
                parser.fail("an unopened group")
            _compile(tree, self._code)
        self._code.append([_MATCH, None, None])

    def fullmatch(self, channel: str) -> bool:
        """Whether the pattern matches the whole of ``channel``.

        Parameters
        ----------
        channel : str
            The channel name.

        Returns
        -------
        bool
            True on a match of the whole name.
        """
        if self.literal is not None:
            return channel == self.literal
        code = self._code
        states = self._closure([0])
        for c in channel:
            step = [pc for pc in states if code[pc][0] == _CHAR and code[pc][1](c)]
            if not step:
                return False
            states = self._closure([pc + 1 for pc in step])
        return any(code[pc][0] == _MATCH for pc in states)

    def _closure(self, starts: list) -> list:
        """The instructions reachable from ``starts`` through SPLIT and JMP: the CHAR and
        MATCH ones, each once."""
        code, seen, out, stack = self._code, set(), [], list(reversed(starts))
        while stack:
            pc = stack.pop()
            if pc in seen:
                continue
            seen.add(pc)
            op, a, b = code[pc]
            if op == _JMP:
                stack.append(a)
            elif op == _SPLIT:
                stack.append(b)
                stack.append(a)
            else:
                out.append(pc)
        return out
