// Host-side arithmetic of the instance transforms of two-level scenes (format
// 1.2, spec 3.10): the one home of the double inverse, the condition number, the
// conservative world box of a mesh box, and the checks of rules 6021-6024. The
// compiler builds InstanceRecords with make_instance(); the validator and the
// deep check (D7) call the same functions, so writer and reader cannot drift.
// (Device code moves rays with transform.h only.)
#pragma once

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"

namespace cwbvh {

/// Largest accepted condition number of an instance's linear part, in the
/// infinity norm (rule 6022, spec 3.10): kappa = ||A||inf * ||A^-1||inf <= 2^20.
inline constexpr double kMaxTransformCondition = 1048576.0;
/// world_to_object may differ from the double inverse X of object_to_world by at
/// most this times the element's scale (rule 6023, spec 3.10): linear part
/// |W[r][c] - X[r][c]| <= 2^-20 * max|X_lin|; translation column
/// |W[r][3] - X[r][3]| <= 2^-20 * sum_c |X[r][c] * t[c]| (t = object_to_world's).
inline constexpr double kInverseTolerance = 0x1p-20;

/// Determinant of the 3x3 linear part, in double (each 2x2 cofactor's products
/// are exact in double; one rounding per difference and per sum).
double affine_determinant(const float m[3][4]);

/// The inverse of the affine map `m`, in double: X_lin = adj(A) / det, X[r][3] =
/// -sum_c X_lin[r][c] * t[c], in that order (fixed: the compiler's output must not
/// depend on the platform). False if the determinant is 0 or not finite, or any
/// element of `m` or of the result is not finite.
bool invert_affine(const float m[3][4], double inv[3][4]);

/// kappa_inf(A) = ||A||inf * ||A^-1||inf (max absolute row sums) of the linear part,
/// in double; +infinity if A is singular or not finite.
double condition_number(const float m[3][4]);

/// Rules 6021-6023 for one instance's pair of matrices (message without a prefix):
/// both finite (6021); object_to_world invertible with condition number <=
/// kMaxTransformCondition (6022); world_to_object within kInverseTolerance of the
/// double inverse (6023).
Result check_instance_transforms(const float object_to_world[3][4], const float world_to_object[3][4]);

/// The conservative world box of the object box [lo, hi] under `m` (spec 3.10):
/// each of the 8 corners is mapped in double (products exact, sums rounded), the
/// double interval is widened by a bound on that rounding, and the result is
/// rounded outward to float (lo down, hi up), so the box contains the exact image
/// of every corner, hence of the object box. Non-finite if the image overflows.
void transform_box(const float m[3][4], const float lo[3], const float hi[3], float out_lo[3], float out_hi[3]);

/// An InstanceRecord placing `mesh` (whose index in MESH is `mesh_index`) with
/// `object_to_world`: world_to_object = RN of the double inverse, world box =
/// transform_box of the mesh's lo/hi. Fails (status kInvalidArgument, the rule the
/// record would break: 6021, 6022, 6026) if the transform is not acceptable.
Expected<InstanceRecord> make_instance(const float object_to_world[3][4], const MeshRecord& mesh,
                                       uint32_t mesh_index, uint32_t source_node);

/// The identity transform (3x4).
void identity_transform(float m[3][4]);

}  // namespace cwbvh
