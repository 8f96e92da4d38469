// `fracvi run`: integrate a problem file (or the built-in problem) and write the results.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/analysis/convergence.hpp"
#include "fracvi/analysis/error_estimate.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/checkpoint.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"
#include "interrupt.hpp"
#include "plot.hpp"
#include "progress.hpp"

namespace fracvi::cli {

Command add_run_command(CLI::App& parent) {
  struct Options {
    std::string file;
    std::string out;
    std::string resume;
    std::vector<std::string> overrides;
    bool quiet = false;
    bool no_plot = false;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "run",
      "Integrate M x'' + R D^(2 alpha) x + grad U(x, t) = f with a fractional variational "
      "integrator (method.scheme; `fracvi methods` lists them) and write trajectory.csv (or "
      "trajectory.npz: output.format), summary.json, problem.toml and plots into the output "
      "directory. Without a problem file, runs the built-in problem (a "
      "forced Duffing oscillator with Bagley-Torvik damping). Exit status: 0 success, 1 "
      "numerical failure (files still written), 2 bad input, 130 interrupted by SIGINT, SIGTERM "
      "or SIGHUP (files written up to the signal, status interrupted).");
  app->add_option("problem", opt->file, "problem file (TOML); see docs/problem-file.md");
  app->add_option("--out", opt->out, "output directory (default ./fracvi-out/<problem name>)");
  app->add_option("--set", opt->overrides,
                  "override a problem value, e.g. --set model.alpha=0.6 (repeatable)");
  app->add_flag("--quiet", opt->quiet,
                "print nothing but errors (no summary, no progress bar; a progress bar is shown on "
                "a terminal for runs longer than a second)");
  app->add_flag("--no-plot", opt->no_plot, "do not draw the PNG plots");
  app->add_option("--resume", opt->resume,
                  "continue the run in this output directory from its checkpoint ([output] "
                  "checkpoint_every), with its problem.toml; the result is bit-for-bit that of an "
                  "uninterrupted run")
      ->type_name("DIR");

  auto run = [opt]() {
    // From here to the end of the command SIGINT, SIGTERM and SIGHUP stop the run at the next
    // step (interrupt.hpp); the files are written and the exit status is 130.
    const InterruptGuard interrupt;
    PreparedRun prepared;
    std::optional<Checkpoint> checkpoint;
    try {
      if (!opt->resume.empty()) {
        if (!opt->file.empty() || !opt->overrides.empty() || !opt->out.empty()) {
          throw UsageError("--resume " + opt->resume +
                           ": a resumed run continues the problem.toml of its directory into it; "
                           "give no problem file, --set or --out with --resume");
        }
        checkpoint = read_checkpoint(opt->resume);
        prepared = prepare_run(checkpoint->spec);
      } else {
        prepared =
            prepare_run(opt->file.empty() ? parse_problem(default_problem_toml(),
                                                          "<built-in problem>", opt->overrides)
                                          : load_problem(opt->file, opt->overrides));
      }
    } catch (const ProblemFileError& e) {
      throw UsageError(e.what());
    } catch (const CheckpointError& e) {
      throw UsageError("--resume " + std::string(e.what()));
    }
    const ProblemSpec& spec = prepared.spec;
    const InitialValueProblem& problem = prepared.problem;
    IntegratorOptions& options = prepared.options;
    options.interrupt = [] { return InterruptGuard::received() != 0; };

    // Everything that can fail before step 1 fails here, in this order: the set-up of the
    // integrator (its storage and the scheme's workspace are allocated now), then the output
    // directory (created and tested for writing), so that neither is found out after the run.
    std::unique_ptr<Integrator> integrator;
    try {
      integrator = std::make_unique<Integrator>(problem, prepared.method, options);
      if (checkpoint) restore_checkpoint(*checkpoint, *integrator);
    } catch (const ValidationError& e) {
      throw UsageError(spec.source + ": " + e.what());
    } catch (const CheckpointError& e) {
      throw UsageError("--resume " + std::string(e.what()));
    }
    const std::filesystem::path dir =
        checkpoint ? prepare_output(opt->resume, {})
                   : prepare_output(opt->out, default_output(spec.name, "", opt->overrides));
    // [output] checkpoint_every: the state after every n-th step, and after the step at which a
    // signal arrived (the integrator stops before the next one), so that --resume loses nothing.
    const auto every = static_cast<std::size_t>(spec.checkpoint_every);
    bool checkpoint_warned = false;
    // The integrator is handed to solve_prepared (which owns it while it runs).
    Integrator* const stepping = integrator.get();
    const auto save_checkpoint = [&](std::size_t k) {
      if (every == 0 || k == 0 || stepping->status() != Status::kRunning) return;
      if (k % every != 0 && InterruptGuard::received() == 0) return;
      try {
        write_checkpoint(dir, spec, *stepping);
      } catch (const std::exception& e) {
        // A lost checkpoint does not stop the run it protects: said once, the run goes on.
        if (!checkpoint_warned) {
          std::fprintf(stderr,
                       "fracvi run: the checkpoint after step %zu could not be written "
                       "(the run goes on): %s\n",
                       k, e.what());
        }
        checkpoint_warned = true;
      }
    };

    Solution solution;
    {
      ProgressBar progress(problem.steps, !opt->quiet);
      // No observer when it would do nothing (no bar, no checkpoints): the call per step and its
      // StepView were ≈ 2 % of a d = 1 step (perf).
      std::function<void(std::size_t)> on_step;
      if (progress.enabled() || every > 0) {
        on_step = [&](std::size_t k) {
          progress.update(k);
          save_checkpoint(k);
        };
      }
      solution = solve_prepared(prepared, std::move(integrator), on_step);
    }
    if (!write_results("run", dir, [&] { write_run_output(dir, spec, solution); })) {
      return kExitNumericalFailure;
    }
    // Kept only where it can serve: an interrupted run. A finished or failed run (a failure is
    // deterministic: a resumed run would fail again) has nothing left to resume.
    if (every > 0 && solution.status != Status::kInterrupted) {
      std::error_code ignored;
      std::filesystem::remove(dir / kCheckpointFile, ignored);
    }
    const bool resumable = every > 0 && solution.status == Status::kInterrupted &&
                           std::filesystem::exists(dir / kCheckpointFile);

    std::string plot_note;
    if (opt->no_plot) {
      remove_plots(dir);
    } else {
      plot_note = draw_plots(dir, opt->quiet);
    }

    if (!opt->quiet) {
      const Eigen::Index last = solution.t.size() - 1;  // the last stored row
      std::printf("fracvi run: %s  (d = %lld, alpha = %g, damping order %g, %s, scheme %s)\n",
                  spec.name.c_str(), static_cast<long long>(spec.dim), spec.alpha, 2 * spec.alpha,
                  spec.convention.c_str(), solution.method.c_str());
      std::printf("  status            %s%s%s\n",
                  solution.ok() ? "success" : to_string(solution.status).data(),
                  solution.message.empty() ? "" : ": ", solution.message.c_str());
      const auto steps_run = static_cast<long long>(
          solution.tolerance_runs.empty() ? problem.steps : solution.tolerance_runs.back().steps);
      const double h_run = (spec.end - spec.start) / static_cast<double>(steps_run);
      std::printf("  steps             %zu of %lld  (h = %g, t in [%g, %g])\n", solution.steps_done,
                  steps_run, h_run, spec.start, spec.end);
      if (!solution.tolerance_runs.empty()) {
        double total = 0.0;
        std::string runs;
        for (const ToleranceRun& r : solution.tolerance_runs) {
          total += r.wall_seconds;
          char item[96];
          std::snprintf(item, sizeof item, "%sN = %zu: %.2e", runs.empty() ? "" : ", ", r.steps,
                        r.error_estimate);
          runs += item;
        }
        std::printf("  tolerance         %.2e: %s  (%zu runs, %.3f s in all)\n", options.tolerance,
                    runs.c_str(), solution.tolerance_runs.size(), total);
      }
      if (solution.t.size() > 0) {
        std::printf("  final time        %.10g\n", solution.t[last]);
        std::printf("  final position    %s\n", row_text(solution.x, last).c_str());
        std::printf("  final velocity    %s\n", row_text(solution.v, last).c_str());
        std::printf("  energy            E_0 = %.10g  ->  E_N = %.10g,  dissipated W_N = %.10g\n",
                    solution.energy[0], solution.energy[last], solution.dissipated[last]);
      }
      const ErrorEstimate& estimate = solution.error_estimate;
      if (std::isfinite(estimate.value)) {
        std::printf("  error estimate    max |x_k - x(t_k)| ~ %.2e  (%s, order %.2f%s; %.3f s)\n",
                    estimate.value, estimate.method.c_str(), estimate.order,
                    std::isfinite(estimate.observed_order) ? " observed" : " declared",
                    estimate.wall_seconds);
      } else {
        std::printf("  error estimate    none: %s\n", estimate.note.c_str());
      }
      if (std::isfinite(estimate.value) && !estimate.note.empty()) {
        std::printf("                    note: %s\n", estimate.note.c_str());
      }
      std::printf("  balance error     max |E_k + W_k - E_0| = %.3e  (consistency check)\n",
                  solution.max_balance_error);
      if (options.mirror) {
        std::printf("  mirror error      max |y_k - x_(N-k)| = %.3e  (consistency check)\n",
                    solution.mirror_error);
      } else {
        std::printf("  mirror error      not run (method.mirror = \"%s\"%s)\n", spec.mirror.c_str(),
                    spec.mirror == "auto" ? ": time.steps x model.dim > 10^6; \"on\" runs it" : "");
      }
      if (!spec.reference.empty()) {
        std::printf("  reference error   max |x_k - x_ref(t_k)| = %.3e\n",
                    max_error(solution, parse_reference(spec.reference)));
      }
      std::printf(
          "  newton            %zu iterations (max %zu per step), %zu factorisation%s, %s linear "
          "solver\n",
          solution.newton_iterations, solution.max_newton_iterations_per_step,
          solution.jacobian_factorizations, solution.jacobian_factorizations == 1 ? "" : "s",
          solution.linear_solver.c_str());
      if (solution.history == "fast") {
        std::printf(
            "  damping memory    fast: %zu exponentials + window of %zu lags, eps = %.1e (%s), "
            "%.3g MB\n",
            solution.history_exponentials, solution.history_window, solution.history_tolerance,
            solution.history_tolerance_auto ? "auto" : "given",
            1e-6 * static_cast<double>(solution.history_bytes));
        const HistoryThreads& use = solution.history_threads;
        if (use.team > 1) {
          const double share = use.pushes > 0 ? 100.0 * static_cast<double>(use.team_pushes) /
                                                    static_cast<double>(use.pushes)
                                              : 0.0;
          // Whole steps split by rows (docs/large-systems.md), or the history's pushes alone.
          const char* label = use.whole_steps ? "step threads   " : "history threads";
          const char* unit = use.whole_steps ? "steps, split by rows" : "pushes";
          if (use.measured) {
            std::printf(
                "  %s   %d measured against 1: on %d for %.0f %% of the %s (%zu of %zu trials "
                "won, %zu lost again to a slow spell)\n",
                label, use.team, use.team, share, unit, use.team_won, use.decisions,
                use.team_dropped);
          } else {
            std::printf("  %s   %d as set (%.0f %% of the %s)\n", label, use.team, share, unit);
          }
        }
      } else if (solution.history != "none") {
        std::printf("  damping memory    %s, %.3g MB\n", solution.history.c_str(),
                    1e-6 * static_cast<double>(solution.history_bytes));
      }
      std::printf("  stored            %lld of %zu states (save_every %zu)\n",
                  static_cast<long long>(solution.t.size()), solution.steps_done + 1,
                  solution.save_every);
      std::printf("  wall time         %.3f s  (set-up %.3f s, stepping %.3f s%s)\n",
                  solution.setup_seconds + solution.wall_time_seconds, solution.setup_seconds,
                  solution.wall_time_seconds, options.mirror ? " with the mirror run" : "");
      if (!spec.events.empty()) {
        std::string crossings;
        for (std::size_t i = 0; i < solution.events.size() && i < 5; ++i) {
          char item[160];
          std::snprintf(item, sizeof item, "%s%s at t = %.10g", crossings.empty() ? "" : ", ",
                        solution.events.names[solution.events.event[i]].c_str(),
                        solution.events.t[i]);
          crossings += item;
        }
        if (solution.events.size() > 5) crossings += ", ...";
        std::printf("  events            %zu crossing%s%s%s (events.csv)\n", solution.events.size(),
                    solution.events.size() == 1 ? "" : "s", crossings.empty() ? "" : ": ",
                    crossings.c_str());
      }
      std::printf("  output            %s/{trajectory.%s,%s%ssummary.json,problem.toml%s}\n",
                  dir.string().c_str(), spec.format.c_str(), spec.times.empty() ? "" : "times.csv,",
                  spec.events.empty() ? "" : "events.csv,",
                  !opt->no_plot && plot_note.empty() ? ",*.png" : "");
      if (!plot_note.empty()) std::printf("  plots             %s\n", plot_note.c_str());
      if (resumable) {
        std::printf("  resume            fracvi run --resume %s\n", dir.string().c_str());
      }
    } else if (!solution.ok() && solution.status != Status::kEvent) {
      report_quiet_failure("run", spec.name, solution.status, solution.message,
                           "after " + std::to_string(solution.steps_done) + " of " +
                               std::to_string(spec.steps) + " steps",
                           dir);
    }
    // A signal during the error estimate leaves the trajectory complete (its status says so)
    // but the command was still asked to stop.
    if (InterruptGuard::received() != 0) return kExitInterrupted;
    // A terminal event is not a failure.
    return solution.ok() || solution.status == Status::kEvent ? kExitSuccess
                                                              : kExitNumericalFailure;
  };
  return {app, run};
}

}  // namespace fracvi::cli
