#!/usr/bin/env python3
"""Checks that the code follows the stage table of docs/architecture.md, so neither can drift:

- every public header (include/modalcal/*.hpp) belongs to exactly one stage of the table, and
  every folder of src/ is a stage;
- no file of a stage (src/<stage>/..., or a public header of the stage) includes a header of a
  later stage: data flow one way;
- the build lists the stages in the table's order (MODALCAL_STAGES in src/CMakeLists.txt), which
  is what the linker's check there enforces for calls.

Usage: check_layering.py SOURCE_DIR. Prints each violation and exits 1 if there is any.
"""
import pathlib
import re
import sys

ROW = re.compile(r"^\|\s*(\d+)\s*\|\s*`?(\w+)`?\s*\|\s*`src/(\w+)/`\s*\|([^|]*)\|")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)


def stage_table(doc):
    """[(stage, folder, [headers])] in the table's order."""
    rows = []
    for line in doc.read_text(encoding="utf-8").splitlines():
        m = ROW.match(line)
        if m:
            headers = re.findall(r"`([\w.]+\.hpp)`", m.group(4))
            rows.append((m.group(2), m.group(3), headers))
    return rows


def main(root):
    root = pathlib.Path(root)
    problems = []
    rows = stage_table(root / "docs" / "architecture.md")
    if not rows:
        print("docs/architecture.md: no stage table found")
        return 1
    rank = {folder: k for k, (_, folder, _) in enumerate(rows)}
    header_stage = {}
    for k, (stage, folder, headers) in enumerate(rows):
        for h in headers:
            if h in header_stage:
                problems.append(f"docs/architecture.md: {h} is listed under two stages")
            header_stage[h] = k

    public = sorted(p.name for p in (root / "include" / "modalcal").glob("*.hpp"))
    for h in public:
        if h not in header_stage:
            problems.append(f"include/modalcal/{h}: in no stage of docs/architecture.md's table")
    for h in header_stage:
        if h not in public:
            problems.append(f"docs/architecture.md: lists {h}, which include/modalcal/ does not have")
    for folder in sorted(p.name for p in (root / "src").iterdir() if p.is_dir()):
        if folder not in rank:
            problems.append(f"src/{folder}/: not a stage of docs/architecture.md's table")

    cmake = (root / "src" / "CMakeLists.txt").read_text(encoding="utf-8")
    m = re.search(r"set\(MODALCAL_STAGES ([\w ]+)\)", cmake)
    library_stages = [folder for _, folder, _ in rows if folder != "cli"]
    if not m or m.group(1).split() != library_stages:
        problems.append("src/CMakeLists.txt: MODALCAL_STAGES is not the table's order of library stages: "
                        + " ".join(library_stages))

    # Sources are listed, not globbed: each stage folder's .cpp files (and the tool's) in
    # src/CMakeLists.txt, the test files in tests/CMakeLists.txt.
    listed = set(re.findall(r"[\w/]+\.cpp", cmake))
    for folder in [folder for _, folder, _ in rows]:
        for source in sorted((root / "src" / folder).glob("*.cpp")):
            if f"{folder}/{source.name}" not in listed:
                problems.append(f"src/{folder}/{source.name}: not listed in src/CMakeLists.txt, so not built")
    test_cmake = (root / "tests" / "CMakeLists.txt").read_text(encoding="utf-8")
    for source in sorted((root / "tests").glob("test_*.cpp")):
        if source.name not in re.findall(r"[\w]+\.cpp", test_cmake):
            problems.append(f"tests/{source.name}: not listed in tests/CMakeLists.txt, so not built")

    def stage_of_include(name):
        if name.startswith("modalcal/"):
            return header_stage.get(name[len("modalcal/"):])
        first = name.split("/")[0]
        return rank.get(first)

    files = [(p, rank[p.relative_to(root / "src").parts[0]]) for p in (root / "src").rglob("*")
             if p.suffix in (".cpp", ".hpp", ".h") and p.relative_to(root / "src").parts[0] in rank]
    files += [(root / "include" / "modalcal" / h, header_stage[h]) for h in public if h in header_stage]
    for path, own in sorted(files):
        for name in INCLUDE.findall(path.read_text(encoding="utf-8")):
            other = stage_of_include(name)
            if other is not None and other > own:
                problems.append(f"{path.relative_to(root)}: stage {rows[own][0]} includes \"{name}\" "
                                f"of the later stage {rows[other][0]}")

    for p in problems:
        print(p)
    print(f"{len(files)} files of {len(rows)} stages checked, {len(problems)} violations")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
