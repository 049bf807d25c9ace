// A whole run as one glTF 2.0 binary (.glb), for Blender, ParaView, three.js (apps/viewer) and
// every other glTF reader: each frame is a node with one mesh (a primitive per sheet, the
// sheet's surface sampled as render/surface.h says, with normals), shown by its scale — 1 in
// its own time step, 0 otherwise — in one STEP animation; obstacles are static meshes; the
// scene's camera (or the automatic framing of every frame) is the file's camera.
//
// Layout (what readers, the viewer and the tests rely on): node 0 is the root, turned −90°
// about x so drape's z-up coordinates stand y-up in glTF, with the children: frame nodes
// "frame_00000", … (mesh k is frame k), then obstacle nodes "obstacle<k>", then the node
// "camera". Positions are drape's own coordinates in float32; primitive s of every frame
// mesh is sheet s, its triangles shared by all frames (accessor reuse). scenes[0].extras.drape
// holds {frames, times (s), surface, samples_per_cell, sheets: [{name, m, n, rows, cols}]}.
//
// Why a writer of our own and not tinygltf: the file is a JSON header (nlohmann_json, already
// used for scenes) and one binary buffer appended frame by frame; tinygltf would hold every
// frame twice (its model, then its serialised buffer) and add a dependency to the program.
// The tests read the files back with their own reader.
#pragma once

#include <render/render.h>

#include <cstdint>
#include <ostream>
#include <span>
#include <string>
#include <vector>

#include <drape/world.h>

#include "scene.h"

namespace drape::app {

struct GltfOptions {
  render::SurfaceKind surface = render::SurfaceKind::Grid;
  int samples_per_cell = 1;  // 1..64
};

class GltfRun {
 public:
  // Throws std::invalid_argument for samples_per_cell outside 1..64.
  GltfRun(const Scene& scene, GltfOptions options);

  // One frame: the sheets in the scene's order, at simulated time `time` (s).
  template <class Real>
  void add_frame(std::span<const SheetView<Real>> sheets, double time);
  int frames() const { return int(times_.size()); }
  // The binary data `frames` frames of `scene` will take (positions and normals; indices,
  // obstacles and the animation not counted): a run can be refused before anything is built
  // (a refused run's triangle indices alone could take gigabytes). Throws std::invalid_argument
  // as the constructor does.
  static std::uint64_t frame_bytes(const Scene& scene, GltfOptions options, std::uint64_t frames);
  static constexpr std::uint64_t max_bytes = 0xFFFFFFFFull;  // a .glb's length is 32-bit

  // Finishes the file (obstacles, camera, animation) and writes the .glb bytes of the frames
  // added. Call once. Throws std::runtime_error when the file would pass glTF's 4 GiB.
  void write(std::ostream& out);

 private:
  struct SheetLayout {
    std::string name;
    std::uint32_t m, n;
    int indices;  // accessor of its triangles
  };
  struct View {
    std::size_t offset, length;
    int target;  // 34962 vertex data, 34963 indices, 0 animation data
  };
  struct Accessor {
    int view, component;  // 5126 float, 5125 unsigned int
    std::size_t count;
    std::string type;     // SCALAR, VEC3
    std::vector<float> lo, hi;  // empty: no bounds written
  };
  int add_view(const void* data, std::size_t bytes, int target);
  int add_accessor(Accessor a);
  int add_floats(std::span<const float> v, const char* type, int target, bool bounds);

  const Scene& scene_;
  GltfOptions options_;
  std::vector<SheetLayout> sheets_;
  std::vector<std::uint8_t> bin_;
  std::vector<View> views_;
  std::vector<Accessor> accessors_;
  std::vector<std::vector<std::pair<int, int>>> frame_primitives_;  // per frame, per sheet: POSITION, NORMAL
  std::vector<double> times_;
  render::Bounds content_;  // every frame's points: frames the camera and sizes a plane
};

}  // namespace drape::app
