// Scene files: a JSON description of one simulation (world, sheets, obstacles, frames,
// output), read into plain engine definitions. Field by field: docs/scene-format.md.
// The loader never half-accepts a file: either every field is valid, or it throws one
// SceneError naming the file, the JSON path of the field and the problem.
#pragma once

#include <drape/drape.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace drape::app {

// The storage and arithmetic type the world runs in: BasicWorld<double> or <float>.
enum class Precision { Float64, Float32 };
std::string_view precision_name(Precision p);

enum class MeshFormat { Obj, Ply, Vtk, Glb };  // Glb: the whole run in one file (gltf.h)
std::string_view mesh_format_name(MeshFormat f);
std::optional<MeshFormat> mesh_format_from_name(std::string_view name);

struct OutputSettings {
  std::filesystem::path dir = "out";      // where frames go; relative to the current directory
  std::vector<MeshFormat> formats{MeshFormat::Obj};
};

// Where a picture of the scene looks from (for `drape render`); optional in the file.
struct Camera {
  Vec3 eye{3, -3, 2};      // m
  Vec3 target{0, 0, 0};    // m
  Vec3 up{0, 0, 1};
  double fov_degrees = 40;
};

struct Scene {
  std::string file;        // as given to load_scene, used in messages
  std::string description;
  WorldDef world;          // dt, gravity, integrator (threads: set by the caller)
  Precision precision = Precision::Float64;
  double fps = 30;         // output frames per simulated second
  int substeps = 1;        // substeps of world.dt per output frame
  int frames = 1;          // output frames after the initial one
  std::vector<std::string> sheet_names;  // one per sheet, "sheet0", … unless named
  std::vector<SheetDef> sheets;
  std::vector<ObstacleDef> obstacles;
  // Constraints with sheets and carriers named by their position in the file: sheet
  // (and other_sheet) .index is the sheet's index in `sheets`, carrier->index the obstacle's
  // in `obstacles` (build_world maps them to the world's ids).
  std::vector<ConstraintDef> constraints;
  OutputSettings output;
  std::optional<Camera> camera;
  std::string source;      // the file's text as read; `drape run` keeps a copy with the frames
  // FNV-1a 64 of the file's bytes and any overrides: equal fingerprints, equal results
  // (a checkpoint records it so a resume refuses another scene's state).
  std::uint64_t fingerprint = 0;

  double frame_time() const { return substeps * world.dt; }  // s between output frames
};

// One message: "FILE: PATH: problem", or "FILE:LINE:COLUMN: syntax error: …".
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One `drape sweep --set PATH=VALUE`: VALUE (JSON, or a bare word taken as a string) put
// at PATH ("dt", "integrator", "sheets[*].stiffness", "sheets[0].damping") of the document
// before it is read, exactly as if the file said so.
struct SceneOverride {
  std::string path;
  std::string value;
};

// Reads and checks a scene file, with overrides applied in order. Throws SceneError.
Scene load_scene(const std::filesystem::path& file, std::span<const SceneOverride> overrides = {});
// The same from text; `file` only names the source in messages.
Scene parse_scene(std::string_view text, const std::string& file);
Scene parse_scene(std::string_view text, const std::string& file, std::span<const SceneOverride> overrides);

// Bytes the world will hold for the scene at its precision (points, springs, scratch).
std::uint64_t estimated_bytes(const Scene& scene);
std::uint64_t estimated_bytes(const SheetDef& sheet, Precision precision);
// Physical memory of this machine in bytes (sysconf); 0 when unknown.
std::uint64_t physical_memory_bytes();

}  // namespace drape::app
