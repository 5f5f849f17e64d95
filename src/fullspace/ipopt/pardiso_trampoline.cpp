// libpardiso.so: PARDISO's calling convention in front of modalcal's structured KKT solver
// (pardiso_trampoline.h says why). Ipopt calls pardisoinit once per solver instance, then
// pardiso with phase 11 (deferred to the first factorization), 22, 33 and -1.

#include "fullspace/ipopt/pardiso_trampoline.h"

#include <atomic>
#include <cstring>

namespace {
std::atomic<modalcal_kkt_handler_t> installed_handler{nullptr};
}

extern "C" {

#define MODALCAL_EXPORT __attribute__((visibility("default")))

MODALCAL_EXPORT void modalcal_set_kkt_handler(modalcal_kkt_handler_t handler) { installed_handler = handler; }

// Its presence tells Ipopt's loader that pardisoinit/pardiso follow PARDISO >= 4.0 (with
// SOLVER, DPARM and ERROR); its value is never read.
MODALCAL_EXPORT int pardiso_ipopt_newinterface = 1;

MODALCAL_EXPORT void pardisoinit(void* handle, const int* /*mtype*/, const int* /*solver*/, int* /*iparm*/,
                                 double* /*dparm*/, int* error) {
  std::memset(handle, 0, 64 * sizeof(void*));
  *error = 0;
}

MODALCAL_EXPORT void pardiso(void** handle, const int* /*maxfct*/, const int* /*mnum*/, const int* /*mtype*/,
                             const int* phase, const int* n, const double* a, const int* ia, const int* ja,
                             int* /*perm*/, const int* nrhs, int* iparm, const int* /*msglvl*/, double* b,
                             double* /*x*/, int* error, double* /*dparm*/) {
  const modalcal_kkt_handler_t handler = installed_handler.load();
  *error = handler ? handler(handle, *phase, *n, a, ia, ja, nrhs ? *nrhs : 0, iparm, b) : -1;
}

}  // extern "C"
