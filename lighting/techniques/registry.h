#pragma once
/// The registry of lighting techniques: one line per technique in registry.cpp, and the only place outside
/// a technique's folder that names it. Scene files, replay/live --technique, the bench sweep, presets and
/// the live window's panel enumerate techniques and their knob tables from here.
///
/// A scene chooses a technique per role: `"technique": {"real": "dlpv", "virtual": "kinect-val"}` ("none":
/// only the shared pass's direct light, shadows and ambient). Shorthands: a technique's name alone takes
/// every role it supports; "A+B" is {"real": A, "virtual": B}; a technique may declare aliases that set
/// knobs (e.g. a variant).
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lighting/knobs.h"
#include "lighting/scene.h"

namespace mrgi::lighting {

class Technique;  // lighting/techniques/technique.h: what create() builds (GL); the registry itself holds none
struct TechniqueSetup;

/// An alias: a name standing for the technique with some knobs set ("lpv-diff").
struct TechniqueAlias {
  std::string name;
  KnobValues knobs;
  std::string description;
};

struct TechniqueInfo {
  std::string name;                          ///< registry name, also the scene-file and CLI spelling
  std::string description;                   ///< one line
  bool real = false, virtualObject = false;  ///< roles it can serve
  std::vector<std::string> stagePrefixes;    ///< profiler stage names it times ("lpv." ...), for the bench's sums
  KnobGroup knobs;                           ///< its scene-file section and knob table
  std::vector<TechniqueAlias> aliases;
  std::function<std::unique_ptr<Technique>(const TechniqueSetup&)> create;
  /// GPU memory an instance will hold (bytes) for these knobs, roles and output size, before it is built.
  /// `frame`: the shared frame group's knobs (RSM and shadow-map sizes); `lights`: how many lights.
  std::function<size_t(const KnobValues& knobs, const KnobValues& frame, bool real, bool virtualObject, int width,
                       int height, size_t lights)>
      estimateBytes;
};

/// Every registered technique, in registry order; the first is the default of a scene that names none.
const std::vector<TechniqueInfo>& techniques();
/// nullptr when unknown.
const TechniqueInfo* findTechnique(const std::string& name);
/// The default technique's name (the registry's first line).
const std::string& defaultTechniqueName();
/// Every knob group: the shared frame group first, then each technique's.
std::vector<const KnobGroup*> knobGroups();
const KnobGroup* findKnobGroup(const std::string& key);
/// Every group of `knobs` completed with defaults (groups missing entirely are added).
void completeKnobs(KnobSet& knobs);

/// Parses a technique string (a name, an alias, "A+B") into roles; alias knobs are written into `knobs`.
/// Throws std::invalid_argument naming the valid spellings.
TechniqueChoice parseTechniqueChoice(const std::string& spelling, KnobSet* knobs);
/// Parses {"real": ..., "virtual": ...} (either may be missing: "none").
TechniqueChoice parseTechniqueRoles(const std::string& real, const std::string& virtualObject, KnobSet* knobs);
/// The canonical spelling of roles: the technique's name when it serves every role it is given (and the
/// other is "none" because it cannot serve it), else "real+virtual".
std::string canonicalName(const TechniqueChoice& c);
/// Every accepted spelling of a single technique string (names, aliases), for --help and errors.
std::vector<std::string> techniqueSpellings();

/// The distinct techniques of a choice ("none" left out), each with the roles it serves.
struct RoleAssignment {
  const TechniqueInfo* info;
  bool real = false, virtualObject = false;
};
std::vector<RoleAssignment> assignRoles(const TechniqueChoice& c);

/// The knobs a choice uses as JSON: {"frame": {...}, <group of each technique in use>: {...}}.
nlohmann::json usedKnobsJson(const TechniqueChoice& c, const KnobSet& knobs);
/// Applies a knob JSON object of that shape to `knobs` (checked; unknown groups or knobs throw
/// std::invalid_argument naming them). Older flat objects ({"resolution": 16, ...}) are accepted too: each
/// name goes to the one group that declares it.
void applyKnobsJson(const nlohmann::json& j, KnobSet& knobs);

/// Whether a profiler stage is a technique's own (one of its stage prefixes).
bool isTechniqueStage(const std::string& stage);
/// Whether a profiler stage belongs to the lighting (frame stages or a technique's).
bool isLightingStage(const std::string& stage);

}  // namespace mrgi::lighting
