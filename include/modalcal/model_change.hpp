#pragma once
/// \file model_change.hpp
/// A change of a model's physics ("effect"): the unit in which model-form diagnosis talks.
/// Synthetic data hide effects in a truth model (`fullspace_calib synth --truth`), and the effect
/// ranking names its candidates the same way, so that a synthetic study shows at a glance whether
/// the diagnosis found what was hidden.
///
/// Every change sets one property and has a canonical name in the dotted `<entity>.<property>`
/// form of calibration parameter targets (`joint2.krx`, `added_mass_top.mass`,
/// `added_spring_base.kz`) and a description in words. Six kinds, written as compact strings:
///
/// | kind | text | name |
/// |---|---|---|
/// | set a property | `joint2.krx=3.1e5`, `foam_top.stiffness_scale=0.6`, `foam.K=4e4` | `joint2.krx` |
/// | add a point mass | `point_mass@top:mass=0.05`, `point_mass@#17:mass=1`, `point_mass@[0.2,0,0.55]:Ixx=1e-4` | `added_mass_top.mass` |
/// | add springs to ground | `spring@base:kz=1e7` | `added_spring_base.kz` |
/// | add a joint | `joint@#17/#42:kx=1e6`, `joint@[0,0,1]/[0,0,1.01]:krx=10` | `added_joint_node17_node42.kx` |
/// | make a support flexible | `support@post_bottom:kx=6e6` | `support_post_bottom.kx` |
/// | scale part of a block | `region@foam/[0,0,0.4]/[0.1,0.1,0.5]:stiffness_scale=0.5` | `foam_region_0p05_0p05_0p45_n12.stiffness_scale` |
///
/// Grammar (spaces around the tokens are allowed):
/// \code{.unparsed}
/// change   := setting | addition
/// setting  := ENTITY "." PROPERTY "=" NUMBER
/// addition := KIND "@" PLACE ["/" PLACE] ":" PROPERTY "=" NUMBER
/// KIND     := point_mass | spring | joint | support   (joint takes two places, the others one)
///           | region                               (BLOCK "/" POINT "/" POINT: a block and a box's corners)
/// PLACE    := NODE_SET | "#" NODE_ID | "[" X "," Y "," Z "]"    (the last: the node nearest the point)
/// \endcode
///
/// - A setting changes an existing property, or creates an absent one where the model allows it:
///   a joint or spring component (kx, ky, kz, krx, kry, krz; absent means 0), a point mass's
///   inertia (Ixx, Iyy, Izz; 0) and a block's stiffness_scale or mass_scale (absent means 1).
/// - A point mass or spring placed on a node set acts at *each* of its nodes (as `springs:` in a
///   problem file does); properties mass, Ixx, Iyy, Izz for a point mass, kx..krz for springs and
///   joints, in global directions. A joint's places must each be one node.
/// - A support change releases the fixity of every node of the place along the component and
///   puts a spring to ground of the given (positive) stiffness there instead, one per node: a
///   support that gives. Every node must be fixed along that component. Its nominal value is
///   +infinity (rigid; `.inf` in data files, null in JSON).
/// - A region is the part of a block whose elements have their centroid in the box between two
///   corners (inclusive). Its properties stiffness_scale and mass_scale multiply the block's own
///   for those elements (absent means 1); its name is the block's with `_region_`, the box's
///   centre (6 significant digits, `.` written `p` and `-` written `m`) and `_n` with its number
///   of elements. The same box again refers to the same region.
/// - Additions at the same place and of the same kind build up one entity:
///   `spring@base:kx=1e6` then `spring@base:ky=1e6` give one spring with two components.
///
/// \code
/// modalcal::Model model = problem.model;
/// modalcal::ModelEffect e = modalcal::apply_model_change(&model, modalcal::parse_model_change("point_mass@top:mass=0.05"));
/// // e.name == "added_mass_top.mass", e.nominal_value == 0, e.value == 0.05
/// \endcode

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/model.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// Where an added entity acts: the nodes of a node set, one node by its external id, or the node
/// nearest a point (mesh or reference node; ties go to the lower index).
struct MODALCAL_EXPORT NodePlace {
  enum class Kind { NodeSet, NodeId, Point };
  Kind kind = Kind::NodeSet;
  std::string node_set;      ///< Kind::NodeSet
  long node_id = 0;          ///< Kind::NodeId
  Vec3 point = Vec3::Zero(); ///< Kind::Point
};

struct MODALCAL_EXPORT ModelChange {
  enum class Kind { SetProperty, AddPointMass, AddSpring, AddJoint, FlexibleSupport, AddRegion };
  Kind kind = Kind::SetProperty;
  std::string entity;              ///< SetProperty: the block, joint, spring or point mass
  /// Additions: one place, two for a joint; a region: the block (as a NodeSet-kind place's name)
  /// and the box's two corners (Point places).
  std::vector<NodePlace> places;
  std::string property;            ///< e.g. "krx", "mass", "stiffness_scale"
  double value = 0;                ///< the property's value in the changed model
};

/// A change as it acts on a particular model: what reports and the effect ranking show
/// (JSON `hidden_effect: [{name, description, value, nominal_value}]`).
struct MODALCAL_EXPORT ModelEffect {
  std::string name;          ///< canonical `<entity>.<property>`, e.g. "added_mass_top.mass"
  std::string description;   ///< in words, e.g. "rotational stiffness about x of joint joint2"
  double value = 0;          ///< in the changed model
  /// Before the change: 0 for absent entities and components, 1 for absent scale factors,
  /// +infinity for a flexible support's stiffness (the nodes were fixed).
  double nominal_value = 0;
};

/// Parses a change string (grammar above).
/// \throws std::invalid_argument "change 'TEXT': ..." naming what is malformed and the expected form.
MODALCAL_EXPORT ModelChange parse_model_change(const std::string& text);

/// The canonical text of a change; parse_model_change(to_string(c)) gives c back (numbers in
/// their shortest round-trip form).
MODALCAL_EXPORT std::string to_string(const ModelChange& change);

/// Applies `change` to `*model` and returns what it did. The model stays valid (Model::validate).
/// \throws std::invalid_argument "change 'TEXT': ..." naming the item and the likely cause: an
///   unknown entity or node set (listing the known ones), an unknown property (listing the
///   entity's), a value out of range, a rotational component on a node without rotations.
///   `*model` is unchanged when it throws.
MODALCAL_EXPORT ModelEffect apply_model_change(Model* model, const ModelChange& change);

/// Applies `changes` in order, as apply_model_change() one after another would, and returns
/// their effects; the model is copied and validated once, not once per change, which matters for
/// the thousands of candidate effects a diagnosis screens at once.
/// \throws std::invalid_argument as apply_model_change(), naming the first change that fails;
///   `*model` is unchanged when it throws.
MODALCAL_EXPORT std::vector<ModelEffect> apply_model_changes(Model* model, const std::vector<ModelChange>& changes);

/// The block (index) and elements a region change (`region@...`) covers on `model`.
/// \throws std::invalid_argument as apply_model_change for a malformed region or unknown block;
///   for another kind of change.
MODALCAL_EXPORT std::pair<int, std::vector<int>> region_elements(const Model& model, const ModelChange& change);

/// The name and description `change` would have on `model`, without changing it.
/// \throws as apply_model_change.
MODALCAL_EXPORT ModelEffect describe_model_change(const Model& model, const ModelChange& change);

/// Words for a property of `model` by its name, e.g. "foam.G" -> "shear modulus of block foam".
/// A name whose entity is unknown is returned as it is.
MODALCAL_EXPORT std::string describe_property(const Model& model, const std::string& property_name);

/// The largest magnitude a number given by a user (in a problem file, a model change or `--set`)
/// may have. No quantity in a consistent unit system comes near it; beyond it, sums of squares in
/// the assembly, the eigen-solve and the misfit overflow, and a run would fail far from the cause.
inline constexpr double kLargestInputMagnitude = 1e100;

/// Why `value` lies outside the physical range of a property, or "" when it lies inside: E, K, G
/// and the scale factors must be positive, Poisson's ratio nu must lie in (-1, 0.5), every other
/// property (density, stiffness components, masses, inertias) must not be negative, and no finite
/// value may exceed kLargestInputMagnitude. `property` is the property's key (`E`) or its full
/// name (`steel.E`). Example: ("steel.nu", 0.5) gives "Poisson's ratio must lie in (-1, 0.5), got 0.5".
MODALCAL_EXPORT std::string property_range_violation(const std::string& property, double value);

/// The value a property of `model` has when it is absent: 1 for a scale factor, +infinity for a
/// component of a flexible support (GroundSpring::replaces_fixity), else 0. `property_name` is
/// `<entity>.<property>`.
MODALCAL_EXPORT double absent_property_value(const Model& model, const std::string& property_name);

/// The properties of `changed` that are absent from `nominal` or have another value there, as
/// effects (nominal_value as absent_property_value when absent), in `changed`'s order,
/// except those named in `excluded` (e.g. the calibration parameters' targets).
MODALCAL_EXPORT std::vector<ModelEffect> property_differences(const Model& nominal, const Model& changed,
                                                              const std::vector<std::string>& excluded = {});

/// Shortest text that reads back as exactly `value` (std::to_chars), e.g. "0.05", "3.1e+05".
MODALCAL_EXPORT std::string format_round_trip(double value);

}  // namespace modalcal
