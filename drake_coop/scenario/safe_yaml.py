"""Guarded reading of untrusted YAML text: size, encoding, aliases, duplicate keys.

A scenario file comes from a user, so before its content reaches
:func:`pydrake.common.yaml.yaml_load_typed` it is read here with bounds on everything that can
cost memory or time:

* the file is read as bytes, at most :data:`MAX_BYTES`, and decoded as strict UTF-8;
* the document is *composed* (a graph of nodes in which an alias is one shared node) and the
  number of nodes it would have once every alias is expanded is counted on that graph, with
  memoization, before anything is constructed; more than :data:`MAX_NODES` is refused (a
  "billion laughs" alias bomb of a few hundred bytes is refused in microseconds);
* a mapping that lists the same key twice is refused, naming the key (YAML itself leaves the
  last one silently winning);
* integers longer than :data:`MAX_INT_DIGITS` digits are refused with their position.

The loader is Drake's own ``_SchemaLoader`` (``yaml_load``'s, a ``SafeLoader``), so that what
passes here is read the same way by ``yaml_load_typed``.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydrake.common.yaml import _SchemaLoader

__all__ = ["MAX_BYTES", "MAX_NODES", "YamlInputError", "load_untrusted", "read_text_file"]

#: Largest scenario file read (bytes); the paper's is 3 kB.
MAX_BYTES = 1_000_000
#: Largest number of YAML nodes once aliases are expanded; the paper's scenario has ~120.
MAX_NODES = 100_000
#: Longest integer literal (digits), below Python's 4300-digit int/str conversion limit; a
#: shorter one that does not fit a float is reported by the scenario's checks, naming its field.
MAX_INT_DIGITS = 4000


class YamlInputError(ValueError):
    """The text cannot be read safely; the message is one line."""


def read_text_file(path: str | Path, what: str = "scenario file") -> str:
    """Read a UTF-8 text file of at most :data:`MAX_BYTES` bytes.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, for messages.

    Returns
    -------
    str
        Its text.

    Raises
    ------
    YamlInputError
        Missing, not a regular file, unreadable, too large or not UTF-8 (one-line message).
    """
    path = Path(path)
    try:
        if not path.exists():
            raise YamlInputError(f"{what} not found: {path}")
        if not path.is_file():
            raise YamlInputError(f"{what} {path} is not a regular file")
        with open(path, "rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise YamlInputError(f"{what} {path} cannot be read: {exc.strerror or exc}") from None
    if len(raw) > MAX_BYTES:
        raise YamlInputError(f"{what} {path} is larger than {MAX_BYTES} bytes")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise YamlInputError(f"{what} {path} is not UTF-8 text (byte {exc.start}: "
                             f"{raw[exc.start:exc.start + 1]!r})") from None


def _expanded_size(root: yaml.Node) -> int:
    """Nodes of the document once aliases are expanded, counted on the shared graph.

    Iterative post-order walk with memoization per node identity: linear in the number of
    *distinct* nodes whatever the expansion factor. Stops counting past :data:`MAX_NODES`.
    """
    sizes: dict[int, int] = {}
    ancestors: set[int] = set()      # nodes whose children are being counted
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        if isinstance(node, yaml.ScalarNode):
            sizes[id(node)] = 1
            continue
        children = ([n for pair in node.value for n in pair]
                    if isinstance(node, yaml.MappingNode) else list(node.value))
        if children_done:
            ancestors.discard(id(node))
            total = 1 + sum(sizes[id(c)] for c in children)
            sizes[id(node)] = min(total, MAX_NODES + 1)
        elif id(node) not in sizes:
            if id(node) in ancestors:
                raise YamlInputError("invalid YAML: an alias refers to its own anchor")
            ancestors.add(id(node))
            stack.append((node, True))
            stack.extend((c, False) for c in children if id(c) not in sizes)
    return sizes[id(root)]


class _GuardedLoader(_SchemaLoader):
    """Drake's YAML loader, refusing duplicate keys and over-long integers."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: set = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue              # '<<: *base' merges are overrides by design
                key = key_node.value if isinstance(key_node, yaml.ScalarNode) else None
                if key is not None and key in seen:
                    raise YamlInputError(
                        f"duplicate key {_cut(key)!r} at line {key_node.start_mark.line + 1}: "
                        "each field may be given once")
                seen.add(key)
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        digits = sum(ch.isdigit() for ch in str(node.value))
        if digits > MAX_INT_DIGITS:
            raise YamlInputError(f"integer of {digits} digits at line {node.start_mark.line + 1}"
                                 f" (at most {MAX_INT_DIGITS})")
        return super().construct_yaml_int(node)


    def construct_tagged(self, tag, node):
        """A ``!Tag {…}`` mapping as a dict with ``_tag``, as Drake's loader reads variants."""
        if not isinstance(node, yaml.MappingNode):
            raise YamlInputError(f"the tag {_cut(tag)!r} at line {node.start_mark.line + 1} "
                                 "must mark a mapping")
        result = self.construct_mapping(node)
        result.update({"_tag": tag})
        return result


_GuardedLoader.add_constructor("tag:yaml.org,2002:int", _GuardedLoader.construct_yaml_int)
_GuardedLoader.add_multi_constructor("", _GuardedLoader.construct_tagged)


def _cut(text: str, n: int = 40) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= n else text[:n] + "…"


def load_untrusted(text: str):
    """Parse one YAML document with the bounds of this module.

    Root-level keys starting with ``_`` are dropped, as :func:`pydrake.common.yaml.yaml_load`
    does (they hold anchors for templates).

    Parameters
    ----------
    text : str
        The YAML document.

    Returns
    -------
    object
        The untyped data (dict, list, str, float, int, bool or None).

    Raises
    ------
    YamlInputError
        Syntax errors, alias expansions beyond :data:`MAX_NODES`, duplicate keys and over-long
        integers, with a one-line message.
    """
    loader = None
    try:
        loader = _GuardedLoader(text)
        node = loader.get_single_node()
        if node is None:
            return None
        size = _expanded_size(node)
        if size > MAX_NODES:
            raise YamlInputError(f"the YAML document expands (through its aliases) to more "
                                 f"than {MAX_NODES} values; a scenario has about 120")
        data = loader.construct_document(node)
    except YamlInputError:
        raise
    except Exception as exc:   # YAMLError, RecursionError, ValueError, TypeError, ...
        raise YamlInputError(f"invalid YAML: {_cut(exc, 200)}") from None
    finally:
        if loader is not None:
            loader.dispose()
    if isinstance(data, dict):
        for key in [k for k in data if isinstance(k, str) and k.startswith("_")]:
            del data[key]
    return data
