#!/usr/bin/env python3
"""Lists the functions of src/ longer than a limit, and fails when there is one.

    check_function_length.py SOURCE_DIR [--limit N] [--list K]

A function's length is the number of lines from its name to its closing brace. Functions defined
inside another function's body (lambdas, local classes) count as part of it. The scan is lexical:
comments, string and character literals are blanked first, then every brace that follows a
parameter list (with qualifiers, a trailing return type or a constructor's initializer list) and
is not inside another function opens one. --list K prints the K longest whatever their length.
"""
import argparse
import pathlib
import re
import sys

CONTROL = {"if", "for", "while", "switch", "catch", "return", "sizeof", "alignof", "decltype", "static_assert"}


def blank_comments_and_literals(text):
    """The text with comments and literals replaced by spaces, newlines kept."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith('R"', i) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = text.find(")" + m.group(1) + '"', i)
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            if c == "'" and i > 0 and text[i - 1].isalnum():  # a digit separator: 1'000'000
                out.append(c)
                i += 1
                continue
            out.append(" " * (j - i))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def function_name(head):
    """The function's name when `head` (the text before a '{') ends a function's declarator, else None."""
    h = head.rstrip()
    # A constructor's initializer list: ") : member_(...), base{...}" -- cut back to the parameter list.
    m = re.search(r"\)\s*(?:noexcept\s*)?:\s*[\w:<>,\s]*[\(\{][^;{}]*$", h)
    if m and not re.search(r"\?\s*[^:]*$", h[: m.start() + 1]):
        h = h[: m.start() + 1]
    h = re.sub(r"(\s*(const|noexcept|override|final|mutable|volatile|&&|&))*$", "", h).rstrip()
    h = re.sub(r"\s*->\s*[\w:<>,\s\*&]+$", "", h).rstrip()  # a trailing return type
    h = re.sub(r"(\s*(const|noexcept|override|final|mutable|&&|&))*$", "", h).rstrip()
    if not h.endswith(")"):
        return None
    depth, i = 0, len(h) - 1
    while i >= 0:
        if h[i] == ")":
            depth += 1
        elif h[i] == "(":
            depth -= 1
            if depth == 0:
                break
        i -= 1
    if i <= 0:
        return None
    before = h[:i].rstrip()
    if before.endswith("]"):  # a lambda
        return None
    m = re.search(r"([~\w:]+(?:<[^<>]*>)?|operator\s*\S+)$", before)
    if not m:
        return None
    name = m.group(1)
    if name.split("::")[-1] in CONTROL or name in CONTROL:
        return None
    return name


def functions(path):
    """(name, first line, last line) of each function defined in `path` outside any other."""
    text = blank_comments_and_literals(path.read_text(encoding="utf-8", errors="replace"))
    found = []
    stack = []  # per open brace: True when it opened a function body at the outermost function level
    inside = 0  # open function bodies
    last_stop = 0
    for i, c in enumerate(text):
        if c == "{":
            is_function = False
            if inside == 0:
                head = text[last_stop:i]
                name = function_name(head)
                if name:
                    is_function = True
                    start = last_stop + len(head) - len(head.lstrip())
                    found.append([name, text.count("\n", 0, start) + 1, None])
            stack.append(is_function)
            inside += is_function
            last_stop = i + 1
        elif c == "}":
            if stack and stack.pop():
                inside -= 1
                found[-1][2] = text.count("\n", 0, i) + 1
            last_stop = i + 1
        elif c == ";":
            last_stop = i + 1
        elif c == "#" and (i == 0 or text[i - 1] == "\n"):  # a preprocessor line ends a declarator
            j = text.find("\n", i)
            last_stop = len(text) if j < 0 else j
    return [(n, a, b) for n, a, b in found if b is not None]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source_dir")
    parser.add_argument("--limit", type=int, default=80)
    parser.add_argument("--list", type=int, default=0)
    args = parser.parse_args()
    root = pathlib.Path(args.source_dir)
    rows = []
    for path in sorted((root / "src").rglob("*")):
        if path.suffix in (".cpp", ".hpp", ".h", ".cc"):
            for name, first, last in functions(path):
                rows.append((last - first + 1, f"{path.relative_to(root)}:{first}", name))
    rows.sort(reverse=True)
    for length, where, name in rows[: args.list]:
        print(f"{length:5d}  {where}  {name}")
    over = [r for r in rows if r[0] > args.limit]
    for length, where, name in over:
        print(f"too long: {name} ({where}) has {length} lines, more than {args.limit}", file=sys.stderr)
    print(f"{len(rows)} functions in src/, the longest {rows[0][0] if rows else 0} lines; "
          f"{len(over)} over {args.limit}")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
