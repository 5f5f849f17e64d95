#!/usr/bin/env python3
"""Every test that tests/CMakeLists.txt names in a label's list (MODALCAL_HEAVY_TESTS,
MODALCAL_GMSH_MESHER_TESTS) exists as a TEST in tests/*.cpp. A name that matches nothing would be
left out of the unlabelled tests and found by no labelled list either: the test it meant to name
would then run nowhere, without a word.

Usage: check_test_labels.py SOURCE_DIR
"""
import pathlib
import re
import sys


def listed_names(cmake_text, variable):
    match = re.search(r"set\(" + variable + r"\s+(.*?)\)\n", cmake_text, re.S)
    if not match:
        sys.exit(f"tests/CMakeLists.txt: no set({variable} ...)")
    joined = "".join(re.findall(r'"([^"]*)"', match.group(1)))
    return [name for name in joined.split(":") if name and "*" not in name]


def main():
    root = pathlib.Path(sys.argv[1])
    cmake_text = (root / "tests" / "CMakeLists.txt").read_text()
    sources = "\n".join(p.read_text() for p in sorted((root / "tests").glob("*.cpp")))
    defined = set(re.findall(r"\bTEST(?:_F)?\(\s*(\w+)\s*,\s*(\w+)\s*\)", sources))
    missing = []
    for variable in ("MODALCAL_HEAVY_TESTS", "MODALCAL_GMSH_MESHER_TESTS"):
        for name in listed_names(cmake_text, variable):
            suite, _, test = name.partition(".")
            if (suite, test) not in defined:
                missing.append(f"{variable}: {name}")
    for line in missing:
        print(f"tests/CMakeLists.txt names a test that does not exist: {line}")
    print(f"{len(missing)} missing")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
