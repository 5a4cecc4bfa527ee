#!/usr/bin/env python3
"""Fails when the repository's files speak of how the work was done instead of the product.

The documentation, comments, strings and tests describe what stylerf does, why, and what it measures.
Words that only make sense to the people who wrote it are flagged:

  - "session" as a period of work ("the forty-second session", "session 43's binary");
  - issue numbers and "the issue" ("issue 37's threshold", "Issue-11", "the issue's 45 minutes");
  - "floor" as an acceptance bar ("floor 1.5: met", "the 8 s floor", "fern's floors", "floor37");
  - "helper" as a person ("a helper's job ran beside it");
  - "today" ("today's recipe": say which recipe, or the commit);
  - private paths on someone's machine (/tmp/probe, /work/runs/..., /root/..., /home/NAME/...).

The patterns are narrow on purpose, so that product text passes: floor() and std::floor, "odd sizes floor"
(rounding), the scene's checker or disc floor, the evaluation's "RGB floor" (the unstylised frames'
score), a helper function, pytest's scope="session", and the temporary paths programs really use
(/tmp/stylerf-*, mktemp templates) are not flagged.

    process_language_check.py ROOT          scan ROOT's files; exit 1 naming file:line and the phrase
    process_language_check.py --self-test   check that planted phrases are found and clean text passes

Files: `git ls-files` (tracked and untracked, not ignored) when ROOT is a git checkout, else every file
under ROOT outside build folders. Binary files are skipped. This file is exempt: it must spell the
patterns and the self-test's planted lines.
"""
import os
import re
import subprocess
import sys
import tempfile

# Files that must contain the words they look for, by path relative to the root.
EXEMPT_FILES = {
    "tests/process_language_check.py",  # the patterns and the self-test's planted phrases
}

# Folders the fallback walk never enters (build outputs, caches, the data set beside the checkout).
SKIPPED_DIRS = {".git", "__pycache__", ".cache", "node_modules", ".venv", "venv", "out", "shared"}

# "floor" as an acceptance bar, not the function, the rounding or the scene's floor.
_NOT_RGB = r"(?<!RGB )(?<!unstylised )(?<!unstylized )"
FLOOR_PATTERNS = [
    r"\bissues?\s+floors?\b",                                           # "issue floors"
    _NOT_RGB + r"\bfloors?\s+\d",                                       # "floor 1.5: met", "floors 0.75x"
    r"(?<!\w)\d[\w.%/-]*\s+(?:[a-z][\w-]*\s+)?floors?\b",               # "the 8 s floor", "1.2x style floor"
    r"\b(?:meets?|met|meeting|miss(?:es|ed|ing)?)\s+(?:\S+\s+){0,3}floors?\b",  # "misses the floor"
    _NOT_RGB + r"\bfloors?(?:'s|s')?\s*(?::|is|are|was|were)?\s*(?:still\s+)?(?:not\s+)?(?:met|missed)\b",
    _NOT_RGB + r"\bfloor's own\b",                                     # "the floor's own command"
    r"\b(?:fern|lego|horns|style|consistency|short-range|long-range|time|speed|LPIPS|RMSE|PSNR|dB)"
    r"(?:'s)?\s+floors?\b",                                             # "fern's floor", "style floor"
    r"\b(?:every|each|neither|either)\s+(?:\S+\s+){0,2}floors?\b",      # "every lego floor"
    r"\bfloor\d",                                                       # "floor37" (a run named after one)
    r"\bbelow floor\b|\bfloor met\b|\bacceptance floors?\b",
]

PATTERNS = [
    ("session", r"\bsessions?\b"),
    ("issue number", r"\bissues?[\s-]*#?\d+"),
    ("the issue", r"\bthe issue(?:'s)?\b"),
    ("acceptance floor", "|".join("(?:%s)" % p for p in FLOOR_PATTERNS)),
    ("helper (a person)", r"\bhelper(?:'s|s')|\ba helper\b(?!\s+(?:function|class|struct|script|program|"
                          r"that|which|to|for|of)\b)"),
    ("today", r"\btoday(?:'s)?\b"),
    ("private path", r"(?<![\w.~$-])/(?:work|root)/[\w.-]+|(?<![\w.~$-])/home/[a-z][\w.-]*/"),
]
COMPILED = [(name, re.compile(p, re.IGNORECASE)) for name, p in PATTERNS]

# /tmp in prose and comments records someone's machine ("the probe in /tmp/probe"); in code it is a path the
# program really uses (a default cache, a mktemp template, a test's output argument), so code is not scanned
# for it. Documentation files are all prose; elsewhere only the comment part of a line is.
TMP_PATH = re.compile(r"(?<![\w.~$-])/tmp\b(?!/stylerf-)(?!/[\w.-]*XXXXXX)")
PROSE_SUFFIXES = (".md", ".txt", ".rst", ".json")
COMMENT_START = re.compile(r"^\s*(?:#|//|/\*|\*)|\s(?://|#)\s")

# Phrases that look like process language but are product text (pytest's fixture scope).
ALLOWED = [re.compile(p) for p in (r"""scope\s*=\s*["']session["']""",)]


def list_files(root):
    """Paths relative to root: git's view of the checkout when there is one, else a walk."""
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                             check=True, capture_output=True).stdout
        if subprocess.run(["git", "-C", root, "rev-parse", "--show-toplevel"], check=True,
                          capture_output=True, text=True).stdout.strip() == os.path.realpath(root):
            return sorted({p for p in out.decode().split("\0") if p and os.path.isfile(os.path.join(root, p))})
    except (OSError, subprocess.CalledProcessError):
        pass
    found = []
    for d, dirs, files in os.walk(root):
        dirs[:] = [x for x in dirs if x not in SKIPPED_DIRS and not x.startswith("build")]
        found += [os.path.relpath(os.path.join(d, f), root) for f in files]
    return sorted(found)


def read_text(path):
    """The file's text, or None for a binary file."""
    with open(path, "rb") as f:
        data = f.read()
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def scan_line(line, prose):
    """(kind, phrase) for each process-language phrase in one line, allowed phrases blanked out first.
    prose: the whole line is documentation (else only its comment part is scanned for /tmp)."""
    for allowed in ALLOWED:
        line = allowed.sub(lambda m: " " * len(m.group(0)), line)
    hits = [(name, m.group(0)) for name, rx in COMPILED for m in rx.finditer(line)]
    comment = line if prose else line[m.start():] if (m := COMMENT_START.search(line)) else ""
    return hits + [("private temporary path", m.group(0)) for m in TMP_PATH.finditer(comment)]


def scan(root):
    """Every hit under root as 'file:line: kind: "phrase"'."""
    hits = []
    for rel in list_files(root):
        if rel.replace(os.sep, "/") in EXEMPT_FILES:
            continue
        text = read_text(os.path.join(root, rel))
        if text is None:
            continue
        prose = rel.endswith(PROSE_SUFFIXES)
        for n, line in enumerate(text.splitlines(), 1):
            hits += ['%s:%d: %s: "%s"' % (rel, n, kind, phrase.strip()) for kind, phrase in scan_line(line, prose)]
    return hits


# Planted lines, each of which must be found, and product lines, none of which may be, by file name.
PLANTED = {
    "notes.md": [
        "Measured in the third session, on the slower host.",
        "As issue 12 asked, the cut stays.",
        "Against the issue's 45 minutes.",
        "Style loss 1.43x (floor 1.5: met).",
        "It misses the 8 s floor here.",
        "Every lego 1/4 floor of the plan is met.",
        "fern's floor is still missed.",
        "the floor's own 90-minute command",
        "(a helper's job ran beside it)",
        "with today's recipe",
        "the probe is /work/runs/s31/probe",
        "`bench/decoder_step_vs_torch.sh /tmp/torchenv/bin/python 256 5`",
        "a `/tmp` program against the library",
    ],
    "cuts.cpp": [
        "// The ray-cost cuts of Issue-11, each against a reference.",
        "const double x = 1.0;  // measured in /tmp/probe",
        "#   python3 -m venv /tmp/torchenv",
    ],
}
CLEAN = {
    "notes.md": [
        "h0 = floor((H - 7) / 4) + 1, and floor(K / parts) chunks; truncation is floor",
        "shapes on a checker floor (z = 0, radius 6); the disc floor of the textured scene",
        "the RGB floor 0.0567 short RMSE against AdaIN's; the RGB floor's own render; rgb (the floor)",
        "Small file helpers shared by everything; a helper function that writes atomically",
        "The style stage keeps a minimum of 15 minutes; $OUT/device_check.json; ../shared/data",
        "The issued commands; a tissue of lies; 42 sessionless calls",
    ],
    "clean.cpp": [
        "const int i0 = int(std::floor(centre));  // odd sizes floor, as torch's MaxPool2d",
        "TEST_CASE(\"conv2d_output_size floors like torch\") {  // (floor: 16 -> 7)",
        "Shape floor; floor.kind = Shape::Kind::disc; static AnalyticScene on_floor();",
        '@pytest.fixture(scope="session")',
        'return "/tmp/stylerf-cache"; STAGE=$(mktemp -d /tmp/device_bundle.XXXXXX)',
        'expect("eval table -o /tmp/x", "must be a density checkpoint");',
        'for (const char* d : {"../shared/data", "../../shared/data"})',
    ],
}


def self_test():
    """Run the scan on a planted folder (each phrase found, exit 1) and on a clean one (nothing, exit 0)."""
    failures = []
    for files, want_hits in ((PLANTED, True), (CLEAN, False)):
        with tempfile.TemporaryDirectory() as d:
            for name, lines in files.items():
                with open(os.path.join(d, name), "w") as f:
                    f.write("\n".join(lines) + "\n")
            hits = scan(d)
            status = subprocess.run([sys.executable, os.path.abspath(__file__), d], capture_output=True).returncode
        hit_lines = {tuple(h.split(":")[:2]) for h in hits}
        for name, lines in files.items():
            for n, line in enumerate(lines, 1):
                if ((name, str(n)) in hit_lines) != want_hits:
                    failures.append(("not found: " if want_hits else "flagged: ") + line)
        if status != (1 if want_hits else 0):
            failures.append("exit status %d on the %s folder" % (status, "planted" if want_hits else "clean"))
    for f in failures:
        print("self-test: " + f)
    print("self-test: %s (%d planted phrases found, %d product lines passed)"
          % ("FAILED" if failures else "ok", sum(map(len, PLANTED.values())), sum(map(len, CLEAN.values()))))
    return 1 if failures else 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) != 2:
        print(__doc__)
        return 2
    hits = scan(argv[1])
    for h in hits:
        print(h)
    if hits:
        print("\n%d phrase(s) of process language: say what the product does, why, and what it measures "
              "(see tests/process_language_check.py)." % len(hits))
        return 1
    print("no process language in %d files" % len(list_files(argv[1])))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
