#pragma once
#include <ctime>
#include <cstdio>
#include <map>
#include <string>
namespace tmp_prof {
inline double cpu_now() { timespec t; clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
inline std::map<std::string, std::pair<double,int>>& table() { static std::map<std::string, std::pair<double,int>> t; return t; }
struct Scope { const char* n; double t0; Scope(const char* name) : n(name), t0(cpu_now()) {} ~Scope() { auto& e = table()[n]; e.first += cpu_now() - t0; e.second++; } };
inline void dump() { for (auto& [k, v] : table()) std::fprintf(stderr, "TIMER %-28s %8.2f s %5d calls\n", k.c_str(), v.first, v.second); table().clear(); }
}
