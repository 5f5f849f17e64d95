// Calibrations shared among the ranks of an MPI job (src/cli/work_farm.hpp): campaign, diagnose
// and study full-vs-reduced under `mpirun --oversubscribe -np 3` give what the same command gives
// alone, and the text encoding that carries results between ranks (TaskCodec) is exact. The
// diagnosis's refits in threads of one process give the serial diagnosis too.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "modalcal/task_map.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::CliRun;
using testing::ReadFile;
using testing::RunCli;
using testing::WriteTempFile;

const std::string kSensedBar = testing::SensedBar();

/// The serial runs with one BLAS thread, as every rank has: the same arithmetic, so that the
/// iterations counted agree too.
void OneBlasThread() { setenv("OPENBLAS_NUM_THREADS", "1", 1); }

/// The tool under `mpirun -np 3` (root may run it: CI runs as root). Fails, rather than skips,
/// where mpirun is missing.
CliRun RunMpi(const std::string& args) {
  const std::string mpirun = MODALCAL_MPIRUN;
  if (mpirun.empty()) return {127, "mpirun not found when the tests were configured: install openmpi-bin"};
  return testing::RunShell("OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OPENBLAS_NUM_THREADS=1 " + mpirun +
                           " --oversubscribe -np 3 " + MODALCAL_CLI + " " + args);
}

/// Two JSON documents alike: the same structure, strings and flags; numbers equal to `tolerance`
/// relative (ranks on other nodes may round differently); keys holding times are not compared.
void ExpectAlike(const nlohmann::json& a, const nlohmann::json& b, double tolerance, const std::string& where) {
  ASSERT_EQ(a.type(), b.type()) << where;
  if (a.is_object()) {
    ASSERT_EQ(a.size(), b.size()) << where;
    for (auto it = a.begin(); it != a.end(); ++it) {
      if (it.key().find("time") != std::string::npos || it.key().find("seconds") != std::string::npos) continue;
      ASSERT_TRUE(b.contains(it.key())) << where << "." << it.key();
      ExpectAlike(it.value(), b[it.key()], tolerance, where + "." + it.key());
    }
  } else if (a.is_array()) {
    ASSERT_EQ(a.size(), b.size()) << where;
    for (size_t i = 0; i < a.size(); ++i) ExpectAlike(a[i], b[i], tolerance, where + "[" + std::to_string(i) + "]");
  } else if (a.is_number() && !a.is_number_integer()) {
    const double x = a.get<double>(), y = b.get<double>();
    EXPECT_NEAR(x, y, tolerance * std::max(1.0, std::abs(x))) << where;
  } else {
    EXPECT_EQ(a, b) << where;
  }
}

TEST(TaskCodec, CarriesNumbersTextsAndVectorsExactly) {
  TaskCodec out;
  const double third = 1.0 / 3;
  out.put(third);
  out.put(std::numeric_limits<double>::quiet_NaN());
  out.put(-std::numeric_limits<double>::infinity());
  out.put(std::string("two\nlines, t 5\n"));
  out.put(Vector::LinSpaced(4, -1e-300, 1e300));
  out.put(std::string());
  TaskCodec in(out.str());
  EXPECT_EQ(in.get_number(), third);
  EXPECT_TRUE(std::isnan(in.get_number()));
  EXPECT_EQ(in.get_number(), -std::numeric_limits<double>::infinity());
  EXPECT_EQ(in.get_text(), "two\nlines, t 5\n");
  EXPECT_EQ(in.get_vector(), Vector::LinSpaced(4, -1e-300, 1e300));
  EXPECT_EQ(in.get_text(), "");
  EXPECT_THROW(in.get_number(), std::runtime_error);  // nothing left
  TaskCodec wrong(out.str());
  EXPECT_THROW(wrong.get_text(), std::runtime_error);  // a number stands first
}

TEST(TaskMap, RunInTurnKeepsTheOrder) {
  const std::vector<std::string> r = run_in_turn(4, [](size_t i) { return std::to_string(i * i); });
  EXPECT_EQ(r, (std::vector<std::string>{"0", "1", "4", "9"}));
}

// Pieces of different lengths on more threads than pieces: every result in its index's place, and
// a failure rethrown only once every piece has run, the lowest index's when several fail.
TEST(TaskMap, RunInThreadsKeepsTheOrderAndRethrowsTheLowestFailure) {
  const TaskMap map = run_in_threads(3);
  std::vector<std::string> expected;
  for (size_t i = 0; i < 7; ++i) expected.push_back(std::to_string(i * i));
  const auto slow_first = [](size_t i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(i == 0 ? 50 : 1));
    return std::to_string(i * i);
  };
  EXPECT_EQ(map(7, slow_first), expected);
  EXPECT_TRUE(map(0, slow_first).empty());
  EXPECT_EQ(run_in_threads(1)(3, slow_first), (std::vector<std::string>{"0", "1", "4"}));

  std::atomic<int> ran{0};
  try {
    map(6, [&](size_t i) -> std::string {
      ++ran;
      if (i == 4) throw std::runtime_error("piece 4");
      if (i == 2) {
        std::this_thread::sleep_for(std::chrono::milliseconds(30));  // fails after piece 4 has
        throw std::invalid_argument("piece 2");
      }
      return "";
    });
    ADD_FAILURE() << "no failure rethrown";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "piece 2");
  }
  EXPECT_EQ(ran.load(), 6);
  EXPECT_THROW(run_in_threads(0), std::invalid_argument);
}

// Two calls of one map at once, from two threads (as the diagnosis's walks side by side make
// them): together they never run more pieces at a time than the map's threads, and each call
// gets its own results in order.
TEST(TaskMap, CallsAtOnceShareTheMapsThreads) {
  const TaskMap map = run_in_threads(2);
  std::atomic<int> running{0}, most{0};
  const auto piece = [&](size_t i) {
    const int now = ++running;
    for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    --running;
    return std::to_string(i);
  };
  const std::vector<std::string> expected = {"0", "1", "2", "3", "4", "5", "6", "7"};
  std::vector<std::string> other;
  std::thread beside([&] { other = map(8, piece); });
  const std::vector<std::string> mine = map(8, piece);
  beside.join();
  EXPECT_EQ(mine, expected);
  EXPECT_EQ(other, expected);
  EXPECT_GE(most.load(), 1);
  EXPECT_LE(most.load(), 2);
}

// Six noisy tests of one bar, one 20 % denser, one data file that does not parse: across three
// ranks (two at work) the campaign's runs and summary are the serial ones; its parts merged agree.
/// Six noisy tests of one bar in DIR/data (unit1-6.yaml), unit6 20 % denser, and unit7.yaml, which
/// does not parse; returns the nominal problem's path.
std::string WriteCampaignData() {
  const std::string nominal = WriteTempFile("nominal.yaml", kSensedBar);
  const std::string dir = std::filesystem::path(nominal).parent_path().string();
  std::filesystem::create_directories(dir + "/data");
  const std::string synth = "synth " + nominal + " --modes 1,2,3,4 --noise-freq 0.002 --noise-shape 0.01 ";
  for (int seed = 1; seed <= 5; ++seed)
    EXPECT_EQ(RunCli(synth + "--seed " + std::to_string(seed) + " -o " + dir + "/data/unit" + std::to_string(seed) +
                     ".yaml")
                  .exit_code,
              0);
  EXPECT_EQ(RunCli(synth + "--truth bar.density=1.2 --seed 6 -o " + dir + "/data/unit6.yaml").exit_code, 0);
  WriteTempFile("data/unit7.yaml", "modes: [oops\n");
  return nominal;
}

TEST(Mpi, CampaignAcrossRanksEqualsTheSerialCampaignAndTheMergeOfItsParts) {
  OneBlasThread();
  const std::string nominal = WriteCampaignData();
  const std::string dir = std::filesystem::path(nominal).parent_path().string();

  CliRun serial = RunCli("campaign " + nominal + " " + dir + "/data --jobs 1 --json " + dir + "/serial.json");
  ASSERT_EQ(serial.exit_code, 0) << serial.output;
  CliRun mpi = RunMpi("campaign " + nominal + " " + dir + "/data --json " + dir + "/mpi.json --plot " + dir +
                      "/mpi.png");
  ASSERT_EQ(mpi.exit_code, 0) << mpi.output;
  EXPECT_NE(mpi.output.find("7 data sets across 3 MPI ranks"), std::string::npos) << mpi.output;
  EXPECT_NE(mpi.output.find("FAILED, skipped"), std::string::npos) << mpi.output;  // reported, and the others ran
  EXPECT_TRUE(std::filesystem::file_size(dir + "/mpi.png") > 0);
  const nlohmann::json a = nlohmann::json::parse(ReadFile(dir + "/serial.json"));
  const nlohmann::json b = nlohmann::json::parse(ReadFile(dir + "/mpi.json"));
  ASSERT_EQ(b["runs"].size(), 7u);
  EXPECT_FALSE(b["runs"][6]["ok"].get<bool>());
  EXPECT_EQ(b["summary"][0]["runs"], 6);
  EXPECT_TRUE(b["summary"][0]["varies_between_tests"].get<bool>());
  // The same calibrations: equal but for rounding, which a tolerance far above it and far below
  // the estimates' standard errors (about 0.2 % of E) allows.
  ExpectAlike(a, b, 1e-6, "campaign");

  // An array job's way: one part per data set, then --merge, in the order given.
  std::string parts;
  for (int k = 1; k <= 7; ++k) {
    const std::string part = dir + "/part" + std::to_string(k) + ".json";
    RunCli("campaign " + nominal + " " + dir + "/data/unit" + std::to_string(k) + ".yaml --json " + part);
    parts += " " + part;
  }
  CliRun merged = RunCli("campaign " + nominal + " --merge" + parts + " --json " + dir + "/merged.json");
  ASSERT_EQ(merged.exit_code, 0) << merged.output;
  const nlohmann::json c = nlohmann::json::parse(ReadFile(dir + "/merged.json"));
  // The runs name their data as given: the folder's files, or the file itself.
  ExpectAlike(a["summary"], c["summary"], 1e-6, "merged summary");
  ASSERT_EQ(c["runs"].size(), 7u);
  for (size_t k = 0; k < 7; ++k) EXPECT_EQ(a["runs"][k]["ok"], c["runs"][k]["ok"]) << k;

  // Bad input to --merge: named, exit 2.
  CliRun bad = RunCli("campaign " + nominal + " --merge " + nominal);
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("not a JSON file"), std::string::npos) << bad.output;
  bad = RunCli("campaign " + nominal);
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
}

// The diagnosis's refits and backward pass across ranks: the same verdict, steps and values.
TEST(Mpi, DiagnosisAcrossRanksEqualsTheSerialDiagnosis) {
  OneBlasThread();
  const std::string study = testing::WriteTipMassStudy();
  const std::string dir = std::filesystem::path(study).parent_path().string();
  CliRun serial = RunCli("diagnose " + study + " --quiet --json " + dir + "/serial.json");
  ASSERT_EQ(serial.exit_code, 0) << serial.output;
  CliRun mpi = RunMpi("diagnose " + study + " --quiet --json " + dir + "/mpi.json");
  ASSERT_EQ(mpi.exit_code, 0) << mpi.output;
  EXPECT_NE(mpi.output.find("the refits across 3 MPI ranks"), std::string::npos) << mpi.output;
  const nlohmann::json a = nlohmann::json::parse(ReadFile(dir + "/serial.json"));
  const nlohmann::json b = nlohmann::json::parse(ReadFile(dir + "/mpi.json"));
  EXPECT_EQ(b["accepted"], nlohmann::json::array({"added_mass_tip.mass"})) << b["accepted"].dump();
  ExpectAlike(a, b, 1e-6, "diagnosis");
}

// The data sets calibrated in threads of one process (campaign's default on a machine with
// several cores): the serial campaign's runs and summary, reported in the data sets' order.
TEST(Threads, CampaignInThreadsEqualsTheSerialCampaign) {
  OneBlasThread();
  const std::string nominal = WriteCampaignData();
  const std::string dir = std::filesystem::path(nominal).parent_path().string();
  CliRun serial = RunCli("campaign " + nominal + " " + dir + "/data --jobs 1 --json " + dir + "/serial.json");
  ASSERT_EQ(serial.exit_code, 0) << serial.output;
  CliRun threaded = RunCli("campaign " + nominal + " " + dir + "/data --jobs 3 --json " + dir + "/threaded.json");
  ASSERT_EQ(threaded.exit_code, 0) << threaded.output;
  EXPECT_NE(threaded.output.find("7 data sets, up to 3 at a time in threads"), std::string::npos) << threaded.output;
  size_t at = 0;
  for (int k = 1; k <= 7; ++k) {  // each run's line, in input order
    const size_t line = threaded.output.find("unit" + std::to_string(k) + ".yaml", at);
    ASSERT_NE(line, std::string::npos) << "unit" << k << " out of order:\n" << threaded.output;
    at = line;
  }
  ExpectAlike(nlohmann::json::parse(ReadFile(dir + "/serial.json")),
              nlohmann::json::parse(ReadFile(dir + "/threaded.json")), 1e-6, "campaign");
}

// The refits in threads of one process (diagnose's default on a machine with several cores): the
// same diagnosis as one refit after another.
TEST(Threads, DiagnosisWithItsRefitsInThreadsEqualsTheSerialDiagnosis) {
  OneBlasThread();
  const std::string study = testing::WriteTipMassStudy();
  const std::string dir = std::filesystem::path(study).parent_path().string();
  CliRun serial = RunCli("diagnose " + study + " --jobs 1 --json " + dir + "/serial.json");
  ASSERT_EQ(serial.exit_code, 0) << serial.output;
  EXPECT_NE(serial.output.find("  refit "), std::string::npos) << serial.output;  // one refit's lines at a time
  CliRun threaded = RunCli("diagnose " + study + " --jobs 3 --json " + dir + "/threaded.json");
  ASSERT_EQ(threaded.exit_code, 0) << threaded.output;
  EXPECT_NE(threaded.output.find("the refits up to 3 at a time, in threads"), std::string::npos) << threaded.output;
  EXPECT_EQ(threaded.output.find("  refit "), std::string::npos) << threaded.output;  // no mixed lines
  const nlohmann::json a = nlohmann::json::parse(ReadFile(dir + "/serial.json"));
  const nlohmann::json b = nlohmann::json::parse(ReadFile(dir + "/threaded.json"));
  EXPECT_EQ(b["accepted"], nlohmann::json::array({"added_mass_tip.mass"})) << b["accepted"].dump();
  ExpectAlike(a, b, 1e-6, "diagnosis");

  CliRun bad = RunCli("diagnose " + study + " --jobs 0");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--jobs"), std::string::npos) << bad.output;
}

// The studies' runs handed out to the ranks: full-vs-reduced's child processes (the same
// successes) and study starts' calibrations (the same report).
TEST(Mpi, StudyAcrossRanksEqualsTheSerialStudy) {
  OneBlasThread();
  const std::string dir = std::filesystem::path(WriteTempFile("marker", "")).parent_path().string();
  const std::string problem = std::string(MODALCAL_SOURCE_DIR) + "/problems/propped-cantilever/synthetic.yaml";
  const std::string common = "study full-vs-reduced " + problem + " --starts 2 --seed 1 --methods fullspace ";
  CliRun serial = RunCli(common + "--out " + dir + "/serial --json " + dir + "/serial.json");
  ASSERT_EQ(serial.exit_code, 0) << serial.output;
  CliRun mpi = RunMpi(common + "--out " + dir + "/mpi --json " + dir + "/mpi.json");
  ASSERT_EQ(mpi.exit_code, 0) << mpi.output;
  EXPECT_NE(mpi.output.find("3 MPI ranks"), std::string::npos) << mpi.output;
  const nlohmann::json a = nlohmann::json::parse(ReadFile(dir + "/serial.json"));
  const nlohmann::json b = nlohmann::json::parse(ReadFile(dir + "/mpi.json"));
  ASSERT_EQ(b["runs"].size(), a["runs"].size());
  for (size_t k = 0; k < a["runs"].size(); ++k) {
    EXPECT_EQ(a["runs"][k]["start_parameters"], b["runs"][k]["start_parameters"]) << k;  // the same starts
    EXPECT_EQ(a["runs"][k]["success"], b["runs"][k]["success"]) << k;
  }
  EXPECT_EQ(a["methods"]["fullspace"]["successes"], b["methods"]["fullspace"]["successes"]);

  // study starts: its calibrations from each start factor, shared the same way.
  const std::string starts = "study starts " + problem + " --factors 0.5 2 ";
  serial = RunCli(starts + "--json " + dir + "/starts-serial.json");
  ASSERT_EQ(serial.exit_code, 0) << serial.output;
  mpi = RunMpi(starts + "--json " + dir + "/starts-mpi.json");
  ASSERT_EQ(mpi.exit_code, 0) << mpi.output;
  const nlohmann::json c = nlohmann::json::parse(ReadFile(dir + "/starts-serial.json"));
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/starts-mpi.json"));
  ExpectAlike(c, d, 1e-6, "study starts");
}

}  // namespace
}  // namespace modalcal
