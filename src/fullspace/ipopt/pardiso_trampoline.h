#pragma once
// Internal: the trampoline library libpardiso.so (pardiso_trampoline.cpp). Ipopt 3.11's linear
// solver loader, asked for `linear_solver pardiso`, dlopen()s "libpardiso.so" and calls the
// PARDISO >= 4.0 entry points; this library, linked into modalcal, is already loaded under that
// SONAME, so those calls land here and are forwarded to the handler modalcal installs (the
// structured KKT solver, fullspace/structured_kkt.hpp). The library holds no numerics and
// exports nothing else under PARDISO's names (a `pardiso_` symbol would resolve to Ipopt's own
// Fortran-named wrapper and recurse).

#ifdef __cplusplus
extern "C" {
#endif

/// One PARDISO call: `handle` is the caller's 64-pointer handle (its first slot is free for the
/// handler's per-instance state), `phase` PARDISO's (11 analysis, 22 factorization, 33 solve,
/// -1 release), the matrix the upper triangle in 1-based CSR (n, a, ia, ja), `nrhs` columns in b
/// (overwritten by the solution). Returns PARDISO's error code (0, -4 or -7 singular, -1 input).
typedef int (*modalcal_kkt_handler_t)(void** handle, int phase, int n, const double* a, const int* ia,
                                      const int* ja, int nrhs, int* iparm, double* b);

/// Installs the handler that every later pardiso() call is forwarded to (null: none, and
/// pardiso() returns -1).
void modalcal_set_kkt_handler(modalcal_kkt_handler_t handler);

#ifdef __cplusplus
}
#endif
