#!/usr/bin/python3
"""What the documentation names must exist, and what it shows must be run.

    docs_references_test.py LOOPWIRE ROOT

ROOT is a source tree: its README.md and docs/*.md are read.

- Commands: every `loopwire WORD` in the Markdown's code (code blocks and `code spans`), in the
  man pages LOOPWIRE writes from its definitions and these examples, and in the configuration
  `loopwire gateway --print-config` prints names a command `loopwire --help` lists.
- Links: every relative link of the Markdown names a file or folder that exists, and its
  #anchor a heading of the page it names.
- Examples: every `loopwire ...` and `curl ...` line of the Markdown's sh blocks is run by one of
  the tests that run them as printed (their rules are mirrored below), or is left out for a
  reason given below. A new example that no test runs fails here until one does.

Prints, per Markdown file, how many of its examples each test runs. Exit 1 on any failure.
"""
import collections
import os
import pathlib
import re
import subprocess
import sys
import tempfile

failures = []
LOOPWIRE = ""  # the binary under test, set by main()


def fail(message):
    failures.append(message)
    print(f"FAIL {message}")


def hidden_command(word):
    """The build's and the shell's commands (__man-pages, __complete) are hidden from --help."""
    return word.startswith("__") and subprocess.run([LOOPWIRE, word, "--help"], capture_output=True).returncode == 0


def commands_of(loopwire):
    """The commands `loopwire --help` lists under Subcommands."""
    text = subprocess.run([loopwire, "--help"], capture_output=True, text=True, check=True).stdout
    section = text.split("Subcommands:", 1)[1].split("\n\n", 1)[0]
    return {line.split()[0] for line in section.splitlines() if line.strip()}


# `loopwire WORD`, options before the command's name skipped; WORD/WORD names several commands.
# A capital WORD is a placeholder (`loopwire COMMAND --help`).
MENTION = re.compile(r"(?<![\w.-])loopwire((?:\s+-v|\s+--profile\s+\S+)*)[ \t]+([a-z_][\w-]*(?:/[a-z_][\w-]*)*)")


def mentions(text):
    for match in MENTION.finditer(text):
        for word in match.group(2).split("/"):
            yield word, text.count("\n", 0, match.start()) + 1


MASK = "\x01"


def markdown_parts(text):
    """(code, prose): fenced blocks and code spans, and the rest, each keeping line numbers."""
    code_lines, prose_lines, fenced = [], [], False
    for line in text.split("\n"):
        if line.startswith("```"):
            fenced = not fenced
            code_lines.append("")
            prose_lines.append("")
        elif fenced:
            code_lines.append(line)
            prose_lines.append("")
        else:
            code_lines.append("")
            prose_lines.append(line)
    prose = "\n".join(prose_lines)
    code = list(code_lines)
    # Code spans may wrap lines: what lies between two backticks of the prose is code. The rest
    # is masked by a character no mention spans, so two spans never join into one.
    masked = []
    inside = False
    for char in prose:
        if char == "`":
            inside = not inside
            masked.append(MASK)
        elif char == "\n":
            masked.append("\n")
        else:
            masked.append(char if inside else MASK)
    span_lines = "".join(masked).split("\n")
    code = [a if a else b for a, b in zip(code, span_lines)]
    return "\n".join(code), prose


def check_commands(where, text, known):
    for word, line in mentions(text):
        if word not in known and not hidden_command(word):
            fail(f"{where}:{line}: `loopwire {word}` names no command (loopwire --help lists: {', '.join(sorted(known))})")


def check_roff_commands(where, text, known):
    """In a man page or a configuration file, a command is what follows code's backtick, bold,
    or the start of a line (an example); prose such as 'the profiles loopwire knows' is not."""
    code = re.compile(r"(?:^[ \t#]*|`|\\fB|^\.B[ \t]+)(loopwire\b[^\n`]*)", re.M)
    for match in code.finditer(text):
        line = text.count("\n", 0, match.start()) + 1
        mention = MENTION.match(match.group(1).replace("\\-", "-").replace("\\fR", " "))
        for word in mention.group(2).split("/") if mention else []:
            if word not in known:
                fail(f"{where}:{line}: `loopwire {word}` names no command")


def slug(heading):
    """The anchor GitHub gives a heading."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    text = re.sub(r"\]\([^)]*\)", "", text).replace("[", "")
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    seen = collections.Counter()
    found = set()
    fenced = False
    for line in path.read_text().split("\n"):
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and (match := re.match(r"#{1,6}\s+(.*)", line)):
            base = slug(match.group(1))
            found.add(base if seen[base] == 0 else f"{base}-{seen[base]}")
            seen[base] += 1
    return found


LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def check_links(root, path, prose):
    for match in LINK.finditer(prose):
        target = match.group(1)
        where = f"{path.relative_to(root)}:{prose.count(chr(10), 0, match.start()) + 1}"
        if re.match(r"[a-z][a-z0-9+.-]*:", target):
            continue  # https:, mailto: ...: not a file of the tree
        file_part, _, anchor = target.partition("#")
        # Lexically: a link is read on GitHub, where symbolic links are not followed.
        linked = pathlib.Path(os.path.normpath((path.parent / file_part if file_part else path).absolute()))
        if not linked.exists():
            fail(f"{where}: link to {target}: no such file or folder")
        elif pathlib.Path(os.path.normpath(root.absolute())) not in [linked, *linked.parents]:
            fail(f"{where}: link to {target} leaves the source tree")
        elif anchor:
            if linked.suffix != ".md":
                fail(f"{where}: link to {target}: an anchor in a file that is not Markdown")
            elif anchor not in anchors(linked):
                fail(f"{where}: link to {target}: {linked.name} has no heading with that anchor "
                     f"(it has: {', '.join(sorted(anchors(linked)))})")


def sh_commands(text):
    """The lines of sh blocks, continuation lines joined."""
    lines, fenced = [], False
    for line in text.split("\n"):
        if line.startswith("```"):
            fenced = line.startswith("```sh") and not fenced
            continue
        if fenced:
            if lines and lines[-1].endswith("\\"):
                lines[-1] = lines[-1][:-1] + line.lstrip()
            else:
                lines.append(line)
    return [line for line in lines if re.match(r"(loopwire|curl) ", line)]


def tests_running(command, tests_dir):
    """Which test runs an example as printed, or why none does. Mirrors the tests' own rules."""
    readme_examples = (re.match(r"loopwire (-v )?(read|write|monitor|dump|restore|decode|describe|help|simulate) ", command)
                       and not re.search(r" URL |\[|DEVICE", command)
                       and not re.search(r"kiln\.json|oven-x", command))
    if readme_examples:
        return "cli_readme_examples", None
    if command.startswith("curl "):
        return "gateway_http_readme", None
    # Copied as printed into a test of the feature: the copy must still be there.
    copied = {"gateway_behaviour": "gateway/gateway_test.sh", "cli_profile_files": "app/profile_files_test.sh"}
    for test, source in copied.items():
        if command.removeprefix("loopwire ") in (tests_dir / source).read_text():
            return test, None
    if re.search(r" URL |\[|DEVICE|FILE", command):
        return None, "a synopsis: placeholders, not a command"
    if command.startswith("loopwire scan "):
        return None, "scan sweeps bauds and parities on a line that answers only some units: minutes of timeouts"
    if "kiln.json" in command:
        return None, "needs the reader's own profile file"
    return None, None


def main():
    global LOOPWIRE
    loopwire, root = sys.argv[1], pathlib.Path(sys.argv[2])
    LOOPWIRE = loopwire
    known = commands_of(loopwire)
    pages = [root / "README.md", *sorted((root / "docs").glob("*.md"))]
    tests_dir = pathlib.Path(__file__).resolve().parent.parent

    ran = collections.defaultdict(collections.Counter)
    for path in pages:
        name = str(path.relative_to(root))
        text = path.read_text()
        code, prose = markdown_parts(text)
        check_commands(name, code, known)
        check_links(root, path, prose)
        for command in sh_commands(text):
            test, reason = tests_running(command, tests_dir)
            if test:
                ran[name][test] += 1
            elif reason:
                ran[name]["not run: " + reason] += 1
            else:
                fail(f"{name}: no test runs `{command}` as printed (add it to one, or give the reason here)")

    config = subprocess.run([loopwire, "gateway", "--print-config"], capture_output=True, text=True, check=True).stdout
    check_roff_commands("gateway --print-config", config, known)
    with tempfile.TemporaryDirectory() as folder:
        subprocess.run([loopwire, "__man-pages", "--output-dir", folder, "--readme", *map(str, pages)], check=True)
        man_pages = sorted(pathlib.Path(folder).glob("man*/*"))
        if len(man_pages) < len(known):
            fail(f"only {len(man_pages)} man pages for {len(known)} commands")
        for page in man_pages:
            check_roff_commands(f"man page {page.name}", page.read_text(), known)

    for name, counts in ran.items():
        print(f"{name}: " + "; ".join(f"{count} {test}" for test, count in sorted(counts.items())))
    print(f"{len(pages)} Markdown files, {len(man_pages)} man pages, the --print-config file: "
          f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
