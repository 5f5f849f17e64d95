// Universal files (UFF/UNV): read_uff() on the input.
#include "fuzz_input.hpp"
#include "modalcal/test_data.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return modalcal::fuzz::read_as_file(data, size, "input.uff",
                                      [](const std::string& path) { (void)modalcal::read_uff(path); });
}
