// `fracvi sweep`: the cases of a sweep file (fracvi/io/sweep.hpp) on local threads, or over MPI
// ranks when started by mpirun (built with MPI; every rank runs cases, rank 0 also hands them out
// one at a time and writes the table).
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "cli.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/io/sweep.hpp"
#include "progress.hpp"

#ifdef FRACVI_HAVE_MPI
#include <mpi.h>

#include <chrono>
#endif

namespace fracvi::cli {

namespace {

// Ctrl-C at the level of the sweep: the first stops handing out cases (those running finish and
// are written; --resume runs the rest), the second ends the process at once (the rows written so
// far are kept either way).
std::atomic<bool> g_stop{false};

extern "C" void on_interrupt(int) {
  g_stop = true;
  std::signal(SIGINT, SIG_DFL);
}

// The tally of the rows as they come in, for the progress line and the closing summary.
struct Tally {
  std::size_t status_column = 0;
  std::map<std::string, std::size_t> by_status;
  std::size_t failures = 0;
  void add(const std::string& row) {
    const auto fields = split_csv_line(row.substr(0, row.size() - 1));
    const std::string& status = fields.at(status_column);
    ++by_status[status];
    if (status != "success" && status != "event") ++failures;  // a terminal event: no failure
  }
  [[nodiscard]] std::string text() const {
    std::string s;
    for (const auto& [status, n] : by_status) {
      s += (s.empty() ? "" : ", ") + std::to_string(n) + " " + status;
    }
    return s;
  }
};

// Where the table goes and what has been done there before.
struct Setup {
  std::filesystem::path dir;
  std::unique_ptr<SweepTable> table;
  std::vector<std::size_t> pending;
};

std::filesystem::path default_sweep_output(const std::string& file) {
  return std::filesystem::path("fracvi-out") / std::filesystem::path(file).stem();
}

Setup open_table(const SweepSpec& sweep, const std::string& out, const std::string& file,
                 bool resume) {
  Setup s;
  s.dir = prepare_output(out, default_sweep_output(file));
  try {
    s.table = std::make_unique<SweepTable>(s.dir, sweep, resume);
  } catch (const SweepError& e) {
    throw UsageError(e.what());
  }
  for (const auto& c : sweep.cases) {
    if (!s.table->done().contains(c.index)) s.pending.push_back(c.index);
  }
  return s;
}

// The cases refused before any run, each named with its parameters (the first few; all are rows).
// A resumed sweep does not repeat those whose rows it has.
void report_invalid(const SweepSpec& sweep, const SweepTable& table) {
  constexpr std::size_t kShown = 10;
  std::size_t n = 0;
  for (const auto& c : sweep.cases) {
    if (c.invalid.empty() || table.done().contains(c.index)) continue;
    if (++n <= kShown) std::fprintf(stderr, "fracvi sweep: refused: %s\n", c.invalid.c_str());
  }
  if (n > kShown) {
    std::fprintf(stderr,
                 "fracvi sweep: ... and %zu more refused cases (status invalid in results.csv)\n",
                 n - kShown);
  }
}

// Rewrites the table in case order and reports it: every row counts, those of earlier runs too.
int finish(const char* where, Setup& setup, const SweepSpec& sweep, std::size_t ran, double seconds,
           bool quiet) {
  setup.table->finish();
  Tally all{1 + sweep.parameters.size(), {}, 0};
  for (const auto& [index, row] : setup.table->rows()) all.add(row);
  const std::size_t done = setup.table->done().size();
  const bool interrupted = done < sweep.cases.size();
  if (!quiet || interrupted) {
    std::fprintf(interrupted ? stderr : stdout,
                 "fracvi sweep: %zu of %zu cases in %s (%s); ran %zu %s in %.3f s, %zu from "
                 "earlier runs%s\n",
                 done, sweep.cases.size(), setup.table->file().string().c_str(), all.text().c_str(),
                 ran, where, seconds, done - ran,
                 interrupted ? "; interrupted: continue with --resume" : "");
  }
  // 130 as for a shell job ended by Ctrl-C; 1 when any case did not succeed.
  if (interrupted) return 130;
  return all.failures == 0 ? kExitSuccess : kExitNumericalFailure;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

int run_local(const SweepSpec& sweep, const std::string& file, const std::string& out, int jobs,
              bool resume, bool quiet) {
  Setup setup = open_table(sweep, out, file, resume);
  report_invalid(sweep, *setup.table);
  Tally tally{1 + sweep.parameters.size(), {}, 0};
  const int threads = std::max(1, std::min<int>(jobs, static_cast<int>(setup.pending.size())));
  if (!quiet) {
    std::printf("fracvi sweep: %zu cases (%zu done before), %zu to run on %d thread%s\n",
                sweep.cases.size(), setup.table->done().size(), setup.pending.size(), threads,
                threads == 1 ? "" : "s");
    std::fflush(stdout);
  }
  const auto start = std::chrono::steady_clock::now();
  std::size_t ran = 0;
  {
    CaseProgress progress(setup.pending.size(), !quiet);
    SweepCaseOptions options;
    options.single_thread = true;
    options.out = setup.dir;
    g_stop = false;
    std::signal(SIGINT, on_interrupt);
    ran = run_sweep_local(
        sweep, setup.pending, jobs, options,
        [&](std::size_t index, const std::string& row) {
          setup.table->append(index, row);
          tally.add(row);
          progress.add(tally.failures);
        },
        &g_stop);
    std::signal(SIGINT, SIG_DFL);
  }
  return finish("here", setup, sweep, ran, seconds_since(start), quiet);
}

#ifdef FRACVI_HAVE_MPI
// Launched by mpirun (OpenMPI sets OMPI_COMM_WORLD_SIZE, PMIx launchers PMIX_RANK): only then is
// MPI initialised, so that a plain `fracvi sweep` never starts MPI's run-time.
bool launched_by_mpirun() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMIX_RANK") != nullptr ||
         std::getenv("PMI_SIZE") != nullptr;
}

struct MpiSession {
  // FUNNELED: rank 0 runs cases on a second thread, which never calls MPI.
  MpiSession() {
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  }
  ~MpiSession() { MPI_Finalize(); }
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
};

constexpr int kTagRequest = 1;  // worker → rank 0: the row of the case it finished ("" at first)
constexpr int kTagAssign = 2;   // rank 0 → worker: the next case, or −1 to stop

// Rank 0: hands out one case at a time to whichever rank asks (dynamic balancing: cases differ in
// cost by orders of magnitude), runs cases itself on a second thread taking them from the same
// list, and appends each row as it arrives. It polls with a short sleep instead of blocking in
// MPI_Recv, which spins a core in OpenMPI (the cases need the cores).
int run_master(const SweepSpec& sweep, const std::string& file, const std::string& out, bool resume,
               bool quiet, int size) {
  std::unique_ptr<Setup> setup;
  std::string setup_error;
  try {
    setup = std::make_unique<Setup>(open_table(sweep, out, file, resume));
  } catch (const std::exception& e) {
    setup_error = e.what();  // every worker is told to stop first, then this is reported
  }
  if (setup) report_invalid(sweep, *setup->table);
  Tally tally{1 + sweep.parameters.size(), {}, 0};
  if (setup && !quiet) {
    std::printf("fracvi sweep: %zu cases (%zu done before), %zu to run on %d MPI ranks\n",
                sweep.cases.size(), setup->table->done().size(), setup->pending.size(), size);
    std::fflush(stdout);
  }
  const auto start = std::chrono::steady_clock::now();
  std::size_t ran = 0;
  int active = size - 1;
  g_stop = false;
  std::signal(SIGINT, on_interrupt);

  // The list of cases, shared by the other ranks' requests and rank 0's own thread.
  std::mutex mutex;
  std::size_t next = 0;
  std::vector<std::string> finished;  // rows of rank 0's thread not yet appended
  bool local_running = setup != nullptr;
  const auto take = [&]() -> long long {
    const std::lock_guard<std::mutex> lock(mutex);
    if (!setup || g_stop || next >= setup->pending.size()) return -1;
    return static_cast<long long>(setup->pending[next++]);
  };
  std::thread local;
  if (setup) {
    local = std::thread([&] {
      SweepCaseOptions options;
      options.single_thread = true;
      options.out = setup->dir;
      for (long long index = take(); index >= 0; index = take()) {
        std::string row;
        try {
          row = run_sweep_case(sweep, sweep.cases[static_cast<std::size_t>(index)], options);
        } catch (...) {  // out of memory or the like, not a failing case: stop this thread
          break;
        }
        const std::lock_guard<std::mutex> lock(mutex);
        finished.push_back(std::move(row));
      }
      const std::lock_guard<std::mutex> lock(mutex);
      local_running = false;
    });
  }
  {
    CaseProgress progress(setup ? setup->pending.size() : 0, !quiet && setup);
    const auto record = [&](const std::string& row) {
      setup->table->append(std::stoull(row), row);
      tally.add(row);
      ++ran;
      progress.add(tally.failures);
    };
    std::string row;
    for (;;) {
      std::vector<std::string> rows;
      bool local_left = false;
      {
        const std::lock_guard<std::mutex> lock(mutex);
        rows.swap(finished);
        local_left = local_running;
      }
      for (const auto& r : rows) record(r);
      if (active == 0 && !local_left) break;
      int flag = 0;
      MPI_Status status;
      if (active > 0) MPI_Iprobe(MPI_ANY_SOURCE, kTagRequest, MPI_COMM_WORLD, &flag, &status);
      if (!flag) {
        std::this_thread::sleep_for(std::chrono::microseconds(100));
        continue;
      }
      int length = 0;
      MPI_Get_count(&status, MPI_CHAR, &length);
      row.resize(static_cast<std::size_t>(length));
      MPI_Recv(row.data(), length, MPI_CHAR, status.MPI_SOURCE, kTagRequest, MPI_COMM_WORLD,
               MPI_STATUS_IGNORE);
      if (!row.empty()) record(row);
      const long long assign = take();
      if (assign < 0) --active;
      MPI_Send(&assign, 1, MPI_LONG_LONG, status.MPI_SOURCE, kTagAssign, MPI_COMM_WORLD);
    }
  }
  if (local.joinable()) local.join();
  std::signal(SIGINT, SIG_DFL);
  if (!setup) throw UsageError(setup_error);
  return finish("on the MPI ranks", *setup, sweep, ran, seconds_since(start), quiet);
}

void run_worker(const SweepSpec& sweep, const std::filesystem::path& dir) {
  SweepCaseOptions options;
  options.single_thread = true;
  options.out = dir;  // save = "trajectory": cases/<case>/ there (a file system all ranks share)
  std::string row;    // empty: the first request
  for (;;) {
    MPI_Send(row.data(), static_cast<int>(row.size()), MPI_CHAR, 0, kTagRequest, MPI_COMM_WORLD);
    long long index = -1;
    MPI_Recv(&index, 1, MPI_LONG_LONG, 0, kTagAssign, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    if (index < 0) return;
    row = run_sweep_case(sweep, sweep.cases.at(static_cast<std::size_t>(index)), options);
  }
}
#endif

}  // namespace

Command add_sweep_command(CLI::App& parent) {
  struct Options {
    std::string file;
    std::string out;
    int jobs = 0;
    bool resume = false;
    bool quiet = false;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "sweep",
      "Run every case of a parameter sweep (a base problem and [sweep] parameters; see "
      "docs/sweep-file.md) and write one row per case to results.csv as the cases finish. Cases "
      "run on local threads (--jobs), or over MPI ranks with `mpirun -n P fracvi sweep ...` (an "
      "MPI build). Exit status: 0 every case succeeded, 1 some case did not (its row says why), "
      "2 bad input, 130 interrupted (continue with --resume).");
  app->add_option("sweep", opt->file, "sweep file (TOML)")->required();
  app->add_option("--out", opt->out, "output directory (default ./fracvi-out/<sweep file name>)");
  app->add_option("--jobs,-j", opt->jobs,
                  "cases run at once on this machine (default: one per core); each case runs on "
                  "one thread unless the sweep sets method.threads")
      ->check(CLI::NonNegativeNumber);
  app->add_flag("--resume", opt->resume,
                "continue the sweep in --out: keep the rows there, run the cases without one");
  app->add_flag("--quiet", opt->quiet, "print nothing but errors (no progress, no summary)");

  auto run = [opt]() {
    SweepSpec sweep;
#ifdef FRACVI_HAVE_MPI
    std::unique_ptr<MpiSession> mpi;
    int rank = 0, size = 1;
    if (launched_by_mpirun()) {
      mpi = std::make_unique<MpiSession>();
      MPI_Comm_rank(MPI_COMM_WORLD, &rank);
      MPI_Comm_size(MPI_COMM_WORLD, &size);
    }
#endif
    try {
      sweep = load_sweep(opt->file);
    } catch (const SweepError& e) {
#ifdef FRACVI_HAVE_MPI
      if (rank != 0) return kExitBadInput;  // every rank reads the same file: rank 0 reports it
#endif
      throw UsageError(e.what());
    }
    const int jobs = opt->jobs > 0
                         ? opt->jobs
                         : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
#ifdef FRACVI_HAVE_MPI
    if (size > 1) {
      if (rank != 0) {
        run_worker(sweep, opt->out.empty() ? default_sweep_output(opt->file)
                                           : std::filesystem::path(opt->out));
        return kExitSuccess;
      }
      return run_master(sweep, opt->file, opt->out, opt->resume, opt->quiet, size);
    }
#else
    // Started by mpirun without MPI built in, every process would run the whole sweep into one
    // directory (all but the first refused by its lock): say what is wrong instead.
    if (const char* n = std::getenv("OMPI_COMM_WORLD_SIZE"); n && std::atoi(n) > 1) {
      throw UsageError("started by mpirun with " + std::string(n) +
                       " ranks, but this fracvi was built without MPI (install libopenmpi-dev and "
                       "configure again); without mpirun it runs on the local cores (--jobs)");
    }
#endif
    return run_local(sweep, opt->file, opt->out, jobs, opt->resume, opt->quiet);
  };
  return {app, run};
}

}  // namespace fracvi::cli
