// Helpers shared by the headless subcommands: input errors that say where, CSV parsing,
// device geometry options.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <CLI/CLI.hpp>
#include <istream>
#include <stdexcept>
#include <string>
#include <vector>

#include "doc/input_error.h"
#include "doc/number_format.h"
#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

// Exit status of the CLI for bad input.
inline constexpr int kExitBadInput = 2;

// Thrown by a subcommand callback to end the program with a status (after its output).
struct CommandExit {
  int status = 0;
};

// Reads numeric CSV records from `in`, one per line. Blank lines and lines starting with '#'
// are skipped. Calls `row(values, line_number)` for each record. Throws InputError naming
// `source`, the line and the column when a field is not a number or the count is not
// `expected_fields` (when > 0).
void ForEachCsvRecord(std::istream& in, const std::string& source, int expected_fields,
                      const std::function<void(const std::vector<double>&, int)>& row);

// Adds --frame A,B,C and --pole D options that fill `geometry` (metres); `given` (optional) is set
// true when either is on the command line (a document's own frame then gives way to it).
void AddGeometryOptions(CLI::App& command, haptics::SpidarGeometry* geometry,
                        bool* given = nullptr);
// Validates geometry options, turning errors into InputError.
void ValidateGeometry(const haptics::SpidarGeometry& geometry);

// True when a --mesher value asks for the lattice surface route: "lattice"; false for
// "tetrahedra" or "" (the command's default, named in the error). Throws InputError naming the
// value and the two choices for anything else.
bool LatticeMesherOption(const std::string& mesher, const char* default_route);

// Checks a --flat-cells value (modeling::SurfaceMeshSettings::flat_coarsen_cells): in [0, 1],
// and 0 with the lattice route (`lattice`), which has no clean-up pass. Throws InputError naming
// the option and how to fix it.
void CheckFlatCellsOption(double flat_cells, bool lattice);

// The warning `spidarcad mesh` and `spidarcad fem` print on stderr when a mesh of a solid at cell
// `cell` (m) holds a volume `off` = (mesh − solid) / solid more than modeling::kSharpVolumeRetry
// away from the solid's (modeling::EstimateSolidVolume): a wall about a cell thick or thinner can
// fall between the grid's planes. `way_out` ends it ("a finer --resolution keeps it"). Empty
// when the volume is within the bound.
std::string VolumeOffWarning(double off, double cell, const std::string& way_out);

}  // namespace spidarcad::app
