// fracvi: the command-line front end. Each subcommand lives in its own *_command.cpp.
#include <filesystem>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/core/version.hpp"

int main(int argc, char** argv) {
  using namespace fracvi::cli;
  CLI::App app{
      "fracvi: fractional variational integrators for M x'' + R D^(2 alpha) x + grad U(x, t) = "
      "f(t)\n(Jimenez & Ober-Bloebaum). alpha is the Lagrangian order; the damping order is 2 "
      "alpha.",
      "fracvi"};
  app.set_version_flag("--version", fracvi::version_string());
  app.require_subcommand(1);
  app.fallthrough(false);
  std::vector<Command> commands{
      add_run_command(app),    add_convergence_command(app), add_compare_command(app),
      add_plot_command(app),   add_weights_command(app),     add_derivative_command(app),
      add_bvp_command(app),    add_residual_command(app),    add_methods_command(app),
      add_action_command(app), add_sweep_command(app)};

  std::string known;
  bool is_known = false;
  for (const auto& c : commands) {
    known += (known.empty() ? "" : ", ") + c.app->get_name();
    is_known = is_known || (argc > 1 && c.app->get_name() == argv[1]);
  }
  if (argc > 1 && argv[1][0] != '-' && !is_known) {
    std::cerr << "fracvi: unknown command '" << argv[1] << "' (commands: " << known
              << "; see fracvi --help)\n";
    return kExitBadInput;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Which subcommand failed, so that the line names it.
    std::string where = "fracvi";
    for (const auto* sub : app.get_subcommands()) where += " " + sub->get_name();
    std::cerr << where << ": " << e.what() << " (see " << where << " --help)\n";
    return kExitBadInput;
  }

  for (auto& command : commands) {
    if (!command.app->parsed()) continue;
    const std::string where = "fracvi " + command.app->get_name() + ": ";
    // Every failure is one line on stderr and an exit status of the README's contract, never an
    // abort: input the commands did not classify themselves is still input (exit 2) when it is
    // an invalid argument, an output path or more memory than the machine has; anything else is a
    // failure of the computation (exit 1).
    try {
      return command.run();
    } catch (const UsageError& e) {
      std::cerr << where << e.what() << '\n';
      return kExitBadInput;
    } catch (const std::bad_alloc&) {
      std::cerr << where
                << "out of memory: the problem needs more memory than is available (reduce "
                   "model.dim or time.steps, or store fewer states with [output] every)\n";
      return kExitBadInput;
    } catch (const std::length_error& e) {
      std::cerr << where << "a size beyond what can be allocated (" << e.what()
                << "): reduce model.dim or time.steps\n";
      return kExitBadInput;
    } catch (const std::filesystem::filesystem_error& e) {
      std::cerr << where << e.path1().string() << ": " << e.code().message() << '\n';
      return kExitBadInput;
    } catch (const std::invalid_argument& e) {
      std::cerr << where << e.what() << '\n';
      return kExitBadInput;
    } catch (const std::exception& e) {
      std::cerr << where << "error: " << e.what() << '\n';
      return kExitNumericalFailure;
    }
  }
  return kExitBadInput;
}
