// The compiled form of an implicit solid: a flat postfix program (tape) over a fixed-size value
// stack. Transforms are folded at compile time into one affine map per primitive, arrays are
// unrolled into copies, so the tape holds only primitives and combining operators; evaluation
// is one switch per instruction, no virtual calls, no recursion.
//
// Real-time safety: every evaluation function is noexcept, allocates nothing (the stack is a
// fixed array on the C stack) and is const, so several threads may evaluate one CompiledSolid
// at once; a 1 kHz haptic tick may call them.
//
// Sign convention: value < 0 inside, > 0 outside, in metres. Gradients are d value / d p_W
// (dimensionless, expressed in the world frame, length <= 1). See implicit_node.h for which
// nodes are exact distances and which are Lipschitz-1 bounds.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/interval.h"

namespace spidarcad::modeling {

// Where an axis-aligned box lies with respect to a solid.
enum class BoxClass {
  kInside,     // the value is < 0 on the whole box
  kOutside,    // the value is > 0 on the whole box
  kAmbiguous,  // the bounds straddle 0: the box may contain surface
};

// A solid compiled to a tape. Build with Compile(); immutable afterwards. A default-constructed
// CompiledSolid is empty: value +∞ (outside) everywhere, zero gradient.
class CompiledSolid {
 public:
  // Largest value stack the evaluator supports (deeper trees are rejected by Compile).
  static constexpr int kMaxStackDepth = 64;
  // Largest tape (instructions) Compile accepts, bounding array unrolling.
  static constexpr int kMaxInstructions = 1 << 20;

  // Validates (ValidateTree) and compiles the tree. Throws ModelError for an invalid tree or a
  // tape beyond kMaxInstructions / kMaxStackDepth. root_path as in ValidateTree.
  static CompiledSolid Compile(const ImplicitNode& root, const std::string& root_path = "");

  // Value at p_W (m).
  double Value(const Eigen::Vector3d& p_W) const noexcept;
  // Value at p_W; writes the gradient d value / d p_W (3, world frame) to *gradient_W.
  double ValueAndGradient(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept;
  // Values at the columns of points_W (3 by N) into values (N, preallocated by the caller).
  // Four points run through the tape per pass (SIMD across points); each value is bit-identical
  // to Value() of its point.
  void Values(const Eigen::Ref<const Eigen::Matrix3Xd>& points_W,
              Eigen::Ref<Eigen::VectorXd> values) const noexcept;
  // Values and gradients at the columns of points_W (3 by N) into values (N) and
  // gradients_W (3 by N), both preallocated by the caller; four points per pass, each
  // bit-identical to ValueAndGradient() of its point.
  void ValuesAndGradients(const Eigen::Ref<const Eigen::Matrix3Xd>& points_W,
                          Eigen::Ref<Eigen::VectorXd> values,
                          Eigen::Ref<Eigen::Matrix3Xd> gradients_W) const noexcept;
  // An interval containing the value at every point of box_W (interval arithmetic, tightened
  // per primitive by its Lipschitz bound value(centre) ± L·half-diagonal).
  Interval Bounds(const Eigen::AlignedBox3d& box_W) const noexcept;
  // Classifies box_W by Bounds(): inside, outside or ambiguous. Conservative: kInside and
  // kOutside are guaranteed, kAmbiguous may be returned for a box that is wholly in or out.
  BoxClass Classify(const Eigen::AlignedBox3d& box_W) const noexcept;

  // A pruned tape for the closed box box_W: Value and ValueAndGradient of the result are
  // bit-identical to this solid's at every point of box_W (outside box_W they are not
  // meaningful). A min/max or smooth blend whose interval bounds over box_W prove that one
  // operand is never selected (strictly, with a margin; ties keep both) is replaced by the
  // other operand and the dead sub-tape is dropped. Returns a copy when nothing can be pruned
  // or box_W is empty. Allocates: call it off the haptic tick.
  CompiledSolid Specialize(const Eigen::AlignedBox3d& box_W) const;

  // Number of tape instructions.
  int instruction_count() const { return static_cast<int>(code_.size()); }
  // What one field evaluation costs, in instructions: one per instruction plus one per profile
  // vertex of every extrusion (its distance visits each edge of the polygon), so an extrusion
  // of a 10,000-point profile costs about 10,000 while instruction_count() says 1. Cost
  // estimates (EstimateSurfaceMesh) multiply evaluation counts by it.
  double EvaluationCost() const noexcept;
  // True when `other` runs the same program: same instructions and bitwise the same constants.
  bool SameTape(const CompiledSolid& other) const noexcept;
  // A hash of the program (FNV-1a over opcodes, constant offsets and constant bits): equal for
  // tapes that SameTape calls equal.
  std::uint64_t TapeHash() const noexcept;
  // Number of primitive instructions (after array unrolling).
  int primitive_count() const { return primitive_count_; }
  // Number of primitive instructions bounded by their Lipschitz bound alone in Bounds() (cones,
  // extrusions): value at the centre ± L × half-diagonal, so over a long thin box they are as
  // wide as its diagonal. O(instructions).
  int LipschitzOnlyCount() const noexcept;
  // Deepest value stack the tape uses.
  int stack_depth() const { return stack_depth_; }

  // Tape opcodes (public for tools that print the tape).
  enum class Op : std::uint8_t {
    kSphere,
    kBox,
    kRoundedBox,
    kCylinder,
    kCapsule,
    kCone,
    kTorus,
    kHalfSpace,
    kExtrusion,
    kMin,
    kMax,
    kMaxNeg,
    kSmoothMin,
    kSmoothMax,
    kSmoothMaxNeg,
    kOffset,
    kShell,
    kNeg,  // negates the top of the stack (emitted only by Specialize)
  };
  // One tape instruction: opcode and the offset of its constants in the constant pool.
  struct Instruction {
    Op op;
    std::uint32_t constants;
  };

 private:
  friend class TapeCompiler;
  template <typename T, typename Primitive>
  T Run(Primitive&& primitive) const noexcept;

  std::vector<Instruction> code_;
  std::vector<double> constants_;
  int primitive_count_ = 0;
  int stack_depth_ = 0;
};

}  // namespace spidarcad::modeling
