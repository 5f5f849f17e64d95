#pragma once
/// \file model.hpp
/// The finite-element model as data: nodes, solid element blocks, node sets and the discrete
/// entities (joints, springs to ground, point masses, rigid couplings, fixed DOFs).
///
/// Every physical property (a block's moduli or density, a joint component, a spring stiffness,
/// a point mass or inertia) lives in one table, Model::properties, under a dotted name
/// `<entity>.<property>` such as `foam.G` or `joint1.kx`. Entities refer to properties by index.
/// A calibration parameter is a name bound to one or more properties (see parameters.hpp), so
/// "the three joints' kx" is one parameter with three targets.
///
/// \code
/// modalcal::Model model;
/// int a = model.add_node(1, {0, 0, 0});
/// ...
/// model.validate();   // throws std::invalid_argument naming the offending entity
/// \endcode

#include <array>
#include <map>
#include <string>
#include <vector>

#include "modalcal/elements.hpp"
#include "modalcal/export.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// Index into Model::properties; kNoProperty marks an absent (zero) component.
using PropertyId = int;
constexpr PropertyId kNoProperty = -1;

struct MODALCAL_EXPORT Property {
  std::string name;  ///< `<entity>.<property>`, unique in the model
  double value = 0;  ///< nominal value in the problem's unit system
};

/// How a block's elasticity is given. Internally both are mapped to bulk and shear modulus:
/// \f$\kappa = E / (3(1-2\nu)),\; G = E / (2(1+\nu))\f$.
enum class ElasticForm { BulkShear, YoungPoisson };

/// A part of a block with its own multipliers, applied on top of the block's: model-form
/// diagnosis's candidates "stiffer or heavier here" (model_change.hpp, `region@...`). Regions of
/// one block may overlap; an element in several carries the product of their multipliers.
struct MODALCAL_EXPORT BlockRegion {
  std::string name;           ///< unique among the model's entities, e.g. "foam_region_0p05_0_0p45_n12"
  std::vector<int> elements;  ///< indices into the block's elements, sorted, unique, non-empty
  PropertyId stiffness_scale = kNoProperty;  ///< 1 when absent
  PropertyId mass_scale = kNoProperty;       ///< 1 when absent
};

struct MODALCAL_EXPORT ElementBlock {
  std::string name;
  SolidType type = SolidType::Hex8;
  std::vector<int> connectivity;  ///< node indices, nodes_per_element(type) per element
  ElasticForm form = ElasticForm::BulkShear;
  PropertyId modulus_a = kNoProperty;  ///< bulk modulus K (BulkShear) or Young's modulus E
  PropertyId modulus_b = kNoProperty;  ///< shear modulus G (BulkShear) or Poisson's ratio nu
  PropertyId density = kNoProperty;
  /// Optional dimensionless multipliers of the block's stiffness and mass (1 when absent);
  /// model-form diagnosis uses them as candidate effects.
  PropertyId stiffness_scale = kNoProperty;
  PropertyId mass_scale = kNoProperty;
  std::vector<BlockRegion> regions;
  int num_elements() const {
    return static_cast<int>(connectivity.size()) / nodes_per_element(type);
  }
};

struct MODALCAL_EXPORT NodeSet {
  std::string name;
  std::vector<int> nodes;  ///< node indices, sorted, unique
};

/// Names of the six spring components, in the order of Joint::stiffness and
/// GroundSpring::stiffness: translations along, then rotations about, x, y, z.
inline const std::vector<std::string> kStiffnessComponentNames{"kx", "ky", "kz", "krx", "kry", "krz"};

/// Two-node six-component spring in a local frame (Sierra-SD Joint2G). Components are
/// kx, ky, kz (translations) and krx, kry, krz (rotations) along/about the frame's rows.
/// Rotational components need both nodes to carry rotations.
struct MODALCAL_EXPORT Joint {
  std::string name;
  int node_a = -1, node_b = -1;
  Mat3 frame = Mat3::Identity();  ///< rows: local x, y, z axes in global coordinates
  std::array<PropertyId, 6> stiffness{kNoProperty, kNoProperty, kNoProperty,
                                      kNoProperty, kNoProperty, kNoProperty};
};

/// Springs from each node of a set to ground, in global directions (kx..krz as for joints).
struct MODALCAL_EXPORT GroundSpring {
  std::string name;
  std::vector<int> nodes;
  /// A flexible support: the springs stand where the nodes were fixed (`support@SET:kx=...`,
  /// model_change.hpp), so an absent component means rigidly held, not free.
  bool replaces_fixity = false;
  std::array<PropertyId, 6> stiffness{kNoProperty, kNoProperty, kNoProperty,
                                      kNoProperty, kNoProperty, kNoProperty};
};

/// A lumped mass at a node, with optional rotary inertia about global axes (needs a node
/// carrying rotations).
struct MODALCAL_EXPORT PointMass {
  std::string name;
  int node = -1;
  PropertyId mass = kNoProperty;
  std::array<PropertyId, 3> inertia{kNoProperty, kNoProperty, kNoProperty};  ///< Ixx, Iyy, Izz
};

/// RBE2-like rigid coupling: the translations of each coupled node follow the six DOFs of the
/// reference node, \f$u_s = u_r + \theta_r \times (x_s - x_r)\f$, imposed by eliminating the
/// coupled nodes' DOFs. The reference node must carry rotations.
struct MODALCAL_EXPORT RigidCoupling {
  std::string name;
  int reference = -1;
  std::vector<int> nodes;
};

/// DOFs fixed to zero on a set of nodes.
struct MODALCAL_EXPORT FixedDofs {
  std::string name;  ///< for messages, e.g. the node set it came from
  std::vector<int> nodes;
  std::array<bool, 6> components{false, false, false, false, false, false};
};

struct MODALCAL_EXPORT Model {
  std::vector<Vec3> coordinates;     ///< one per node
  std::vector<long> node_ids;        ///< external (file) ids, for messages and sensors
  std::vector<bool> has_rotations;   ///< node carries six DOFs instead of three
  std::vector<ElementBlock> blocks;
  std::vector<NodeSet> node_sets;
  std::vector<Joint> joints;
  std::vector<GroundSpring> ground_springs;
  std::vector<PointMass> point_masses;
  std::vector<RigidCoupling> rigid_couplings;
  std::vector<FixedDofs> fixed;
  std::vector<Property> properties;
  /// Mode families named by the global direction that dominates them, e.g. {"axial", 0}.
  std::map<std::string, int> mode_families;

  int num_nodes() const { return static_cast<int>(coordinates.size()); }
  int add_node(long id, const Vec3& x, bool rotations = false);
  /// Adds a property; throws std::invalid_argument if the name exists.
  PropertyId add_property(const std::string& name, double value);
  /// Index of a property, or kNoProperty.
  PropertyId find_property(const std::string& name) const;
  /// Value of a property, 0 for kNoProperty.
  double property_value(PropertyId id) const { return id == kNoProperty ? 0.0 : properties[id].value; }
  const NodeSet* find_node_set(const std::string& name) const;
  /// Index of the node with external id `id`, or -1.
  int find_node(long id) const;
  /// Total number of elements over all blocks.
  int num_elements() const;
  /// Checks references and values (node indices, orientations, rotations where needed,
  /// positive densities, orthonormal joint frames, no node both fixed and rigidly coupled
  /// twice, ...). Throws std::invalid_argument naming the entity and the likely cause.
  void validate() const;
};

/// The diagonal of the bounding box of `model`'s nodes: its size (0 without nodes).
MODALCAL_EXPORT double bounding_box_diagonal(const Model& model);

/// Name of a global direction index 0..5 ("x", "y", "z", "rx", "ry", "rz").
MODALCAL_EXPORT std::string component_name(int component);
/// Inverse of component_name; -1 if unknown.
MODALCAL_EXPORT int component_from_name(const std::string& name);

}  // namespace modalcal
