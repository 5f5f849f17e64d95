// The CSV form of test data: read_test_data() on an input named .csv (read_test_csv()).
#include "fuzz_input.hpp"
#include "modalcal/test_data.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return modalcal::fuzz::read_as_file(data, size, "input.csv",
                                      [](const std::string& path) { (void)modalcal::read_test_data(path); });
}
