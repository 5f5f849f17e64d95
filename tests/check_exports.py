#!/usr/bin/env python3
"""Checks what libmodalcal.so exports: the API of include/modalcal/ and nothing else.

    check_exports.py LIBRARY

Lists the library's defined dynamic symbols (nm -DC) and fails on one of modalcal::detail
(internals) or of another library (Ipopt, yaml-cpp, nlohmann, Eigen, Spectra, MUMPS, ...)
instantiated inside. Allowed besides the API: template code instantiated over the API's own types
(std::vector<modalcal::Parameter>, ...), the standard library's own templates (libstdc++ declares
namespace std with default visibility, so its implicit instantiations stay visible whatever
-fvisibility says; they are weak and harmless), and the linker's _edata, _end, __bss_start.
Prints the count of exported symbols, how many are the standard library's, and offending ones.
"""
import subprocess
import sys


def exported_symbols(library):
    out = subprocess.run(["nm", "-DC", "--defined-only", library], check=True, capture_output=True, text=True).stdout
    symbols = []
    for line in out.splitlines():
        parts = line.split(" ", 2)
        if len(parts) == 3 and parts[1] not in ("A",):  # A: version nodes, not code or data
            symbols.append(parts[2])
    return symbols


LINKER_SYMBOLS = {"_edata", "_end", "__bss_start"}
STANDARD_PREFIXES = ("std::", "void std::", "__gnu_cxx::", "typeinfo for std::", "typeinfo name for std::",
                     "vtable for std::", "guard variable for std::")
OTHER_LIBRARIES = ("Eigen::", "YAML::", "nlohmann::", "Ipopt::", "Spectra::", "gmsh::", "cholmod_", "dmumps")


def is_standard_library(symbol):
    return symbol.startswith(STANDARD_PREFIXES) and not any(lib in symbol for lib in OTHER_LIBRARIES)


def offence(symbol):
    if "modalcal::detail::" in symbol:
        return "internal (modalcal::detail)"
    if "modalcal::" in symbol or symbol in LINKER_SYMBOLS or is_standard_library(symbol):
        return None
    return "not the library's API"


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    symbols = exported_symbols(sys.argv[1])
    bad = [(s, why) for s in symbols if (why := offence(s))]
    standard = sum(1 for s in symbols if "modalcal::" not in s and is_standard_library(s))
    print(f"{sys.argv[1]}: {len(symbols)} exported symbols ({standard} the standard library's own templates), "
          f"{len(bad)} outside the API")
    for s, why in bad[:40]:
        print(f"  {why}: {s}")
    if not symbols:
        print("no exported symbols: the library exports nothing at all")
        return 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
