#pragma once
// The tools' command lines through CLI11: typed, range-checked options and --help.
#include <CLI/CLI.hpp>

namespace fruit_shape_completion {

// Parses argv into `app`'s options. Returns 0 after printing --help, 2 after printing what is
// wrong with a bad command line (CLI11 names the option and the value), -1 to go on.
inline int parseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return -1;
}

}  // namespace fruit_shape_completion
