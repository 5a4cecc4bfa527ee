#!/usr/bin/env python3
"""Fails when a C++ function in lib/, host/ or examples/ is longer than 100 lines.

A long function does several things; splitting it into functions with one purpose each keeps it readable.
The length of a function is counted from the line of its name to the line of its closing brace, both
included. Lambdas and local classes count toward the function they are written in.

    function_length_check.py ROOT            check ROOT/lib, ROOT/host, ROOT/examples
    function_length_check.py --self-test     check that the scanner finds a planted 101-line function

The scanner is a brace matcher over the source with comments, strings and character literals blanked
out; it needs no compiler. A brace opens a function body when it follows a parameter list outside any
other function body (namespaces, classes and struct bodies are looked into).
"""
import os
import re
import sys
import tempfile

LIMIT = 100
SCANNED_DIRS = ("lib", "host", "examples")
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".cc", ".inl")
# Heads of braces that open a scope which may hold function definitions.
SCOPE_KEYWORDS = re.compile(r"\b(namespace|class|struct|union|enum)\b|\bextern\s*\"")
# Heads of braces that are never a function body even when they hold parentheses.
NOT_A_BODY = re.compile(r"=\s*$|=\s*[\w:<>, ]*\s*$|\breturn\b|\bdecltype\b")


def blank_literals(text):
    """The source with comments, string and character literals replaced by spaces, newlines kept."""
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
        elif c == "R" and text.startswith('R"', i) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            open_paren = text.find("(", i + 2)
            delim = text[i + 2:open_paren]
            j = text.find(")" + delim + '"', open_paren)
            j = n if j < 0 else j + len(delim) + 2
            out.append('""' + re.sub(r"[^\n]", " ", text[i + 2:j]))
            i = j
        elif c in "\"'":
            # A ' between digits is a C++14 digit separator, not a character literal.
            if c == "'" and i > 0 and text[i - 1].isalnum() and i + 1 < n and text[i + 1].isalnum():
                out.append(" ")
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(c + " " * max(0, j - i - 2) + c)
            i = j
        elif c == "#" and (i == 0 or text[i - 1] == "\n" or text[:i].rsplit("\n", 1)[-1].strip() == ""):
            # Preprocessor lines (with continuations) hold no function bodies.
            j = i
            while True:
                k = text.find("\n", j)
                if k < 0:
                    k = n
                    break
                if text[k - 1] != "\\":
                    break
                j = k + 1
            out.append(re.sub(r"[^\n]", " ", text[i:k]))
            i = k
        else:
            out.append(c)
            i += 1
    return "".join(out)


def function_name(head):
    """The (qualified) name before the parameter list of a function head, or None when there is none."""
    depth = 0
    for pos, c in enumerate(head):
        if c in "<":
            depth += 1 if re.search(r"[\w\s]$", head[:pos]) and not re.search(r"operator\s*$", head[:pos]) else 0
        elif c == ">" and depth > 0 and head[pos - 1] != "-":
            depth -= 1
        elif c == "(" and depth == 0:
            m = re.search(r"((?:[\w~]+(?:<[^()]*>)?::)*(?:operator\s*(?:\(\)|[^\s(]+)|~?\w+))\s*$", head[:pos])
            return m.group(1) if m else None
    return None


def initializer_list_open(head):
    """True when head ends inside a constructor's member initializer list: `) : a_(x), b_`."""
    depth = 0
    for pos, c in enumerate(head):
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif c == ":" and depth == 0 and head[pos - 1:pos + 2].count(":") == 1 and ")" in head[:pos]:
            return re.search(r"[\w>]\s*$", head) is not None
    return False


def functions(text):
    """(name, first line, last line) of every function definition in one source text."""
    code = blank_literals(text)
    found = []
    # Each stack entry: kind ('scope', 'body', 'inner', 'init'), the head's start offset, and the name.
    stack = []
    head_start = 0
    for pos, c in enumerate(code):
        if c == ";":
            if not any(kind in ("body", "init") for kind, _, _ in stack):
                head_start = pos + 1
        elif c == "{":
            in_body = any(kind == "body" for kind, _, _ in stack)
            head = code[head_start:pos]
            if in_body:
                stack.append(("inner", pos, None))
                continue
            if initializer_list_open(head):
                stack.append(("init", head_start, None))
                continue
            name = function_name(head)
            if name and not SCOPE_KEYWORDS.match(head.strip()) and not NOT_A_BODY.search(head.split("(")[0]):
                stack.append(("body", head_start + len(head) - len(head.lstrip()), name))
            else:
                stack.append(("scope", pos, None))
                head_start = pos + 1
        elif c == "}":
            if not stack:
                continue
            kind, start, name = stack.pop()
            if kind == "body":
                first = code.count("\n", 0, start) + 1
                name_at = code.find(name.split("::")[-1], start)
                if name_at >= 0:
                    first = code.count("\n", 0, name_at) + 1
                found.append((name, first, code.count("\n", 0, pos) + 1))
                head_start = pos + 1
            elif kind == "scope":
                head_start = pos + 1
    return found


def long_functions(root, limit=LIMIT):
    """'file:function:lines' for each function in root's scanned folders longer than limit lines."""
    report = []
    for folder in SCANNED_DIRS:
        for dirpath, _, files in os.walk(os.path.join(root, folder)):
            for file in sorted(files):
                if not file.endswith(SOURCE_SUFFIXES):
                    continue
                path = os.path.join(dirpath, file)
                with open(path, encoding="utf-8", errors="replace") as f:
                    text = f.read()
                for name, first, last in functions(text):
                    length = last - first + 1
                    if length > limit:
                        report.append((length, f"{os.path.relpath(path, root)}:{name}:{length}"))
    return [line for _, line in sorted(report, reverse=True)]


def self_test():
    """The scanner must find a planted 101-line function and pass one of 100 lines, beside look-alikes."""
    def body(lines):
        return "".join(f"  total += {i};  // a brace in a comment {{\n" for i in range(lines - 2))
    source = (
        "#include <string>\n"
        "namespace demo {\n"
        "struct Holder { int a{1}; };\n"
        "static const int kTable[] = {1, 2, 3};\n"
        "class Widget {\n public:\n  Widget(int v) : value_{v}, other_(v) {\n" + body(100) + "  }\n"
        "  int value_, other_;\n};\n"
        "int planted_too_long(int total) {\n" + body(101) + "}\n"
        "int exactly_at_limit(int total) {\n" + body(100) + "}\n"
        "std::string text() { return R\"(a { brace in a raw string)\" \"}\"; }\n"
        "}  // namespace demo\n")
    with tempfile.TemporaryDirectory() as root:
        os.makedirs(os.path.join(root, "lib"))
        with open(os.path.join(root, "lib", "planted.cpp"), "w") as f:
            f.write(source)
        report = long_functions(root)
        lengths = {name: last - first + 1 for name, first, last in functions(source)}
    expected = [os.path.join("lib", "planted.cpp") + ":planted_too_long:101"]
    problems = []
    if report != expected:
        problems.append(f"expected {expected}, got {report}")
    for name, length in (("exactly_at_limit", 100), ("Widget", 100), ("text", 1)):
        if lengths.get(name) != length:
            problems.append(f"{name}: expected {length} lines, got {lengths.get(name)}")
    for problem in problems:
        print("self-test:", problem)
    return not problems


def main(argv):
    if argv[1:] == ["--self-test"]:
        ok = self_test()
        print("self-test", "passed" if ok else "FAILED")
        return 0 if ok else 1
    if len(argv) != 2:
        print(__doc__)
        return 2
    if not self_test():
        print("the scanner fails its own self-test; its findings would not be trusted")
        return 1
    report = long_functions(argv[1])
    for line in report:
        print(line)
    if report:
        print(f"{len(report)} function(s) over {LIMIT} lines: split each into functions with one purpose")
        return 1
    print(f"no function over {LIMIT} lines in {', '.join(SCANNED_DIRS)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
