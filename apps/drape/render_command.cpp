// `drape render`: gather one frame's points (by simulating the scene, or by reading the frame
// file back), choose the camera, draw the wireframe and write the PNG atomically.
#include "render_command.h"

#include <render/render.h>
#include <render/surface.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>

#include "export.h"
#include "run.h"
#include "scene.h"

namespace drape::app {

namespace fs = std::filesystem;

namespace {

// One frame's points in double precision (the rasteriser's), one entry per sheet.
struct Frame {
  std::vector<std::vector<double>> x, y, z;
};

// A failure with its exit code; caught once in render_command().
struct Failure {
  int code;
  std::string message;
};

std::optional<std::pair<int, int>> parse_size(const std::string& text) {
  const auto cross = text.find('x');
  if (cross == std::string::npos) return std::nullopt;
  int w = 0, h = 0;
  const char* end = text.data() + text.size();
  const auto a = std::from_chars(text.data(), text.data() + cross, w);
  const auto b = std::from_chars(text.data() + cross + 1, end, h);
  if (a.ec != std::errc() || a.ptr != text.data() + cross || b.ec != std::errc() || b.ptr != end) return std::nullopt;
  if (w < 1 || h < 1 || w > 8192 || h > 8192) return std::nullopt;
  return std::pair{w, h};
}

// Steps frame by frame, as `drape run` does, so both give the same states bit for bit; keeps
// the states of the wanted frames.
template <class Real>
std::map<int, Frame> simulate(const Scene& scene, const std::vector<int>& wanted) {
  std::vector<SheetId> ids;
  BasicWorld<Real> world = build_world<Real>(scene, 0, ids);
  const int last = *std::max_element(wanted.begin(), wanted.end());
  std::map<int, Frame> frames;
  for (int k = 0; k <= last; ++k) {
    if (k > 0) {
      // the engine's stability guard, as in `drape run`: non-finite, or energy without bound
      const drape::StabilityReport report = world.step(scene.substeps);
      if (!report.ok() || !world.all_finite())
        throw Failure{exit_unstable, scene.file + ": the simulation became unstable during frame " + std::to_string(k) +
                                         ", before frame " + std::to_string(last) + "; `drape run` says what to change"};
    }
    if (std::find(wanted.begin(), wanted.end(), k) == wanted.end()) continue;
    Frame& f = frames[k];
    for (SheetId id : ids) {
      const auto v = world.view(id);
      f.x.emplace_back(v.x.begin(), v.x.end());
      f.y.emplace_back(v.y.begin(), v.y.end());
      f.z.emplace_back(v.z.begin(), v.z.end());
    }
  }
  return frames;
}

// frame_NNNNN.{obj,vtu,ply} in `dir`: frame number → the file to read (OBJ before VTU before PLY).
std::map<int, fs::path> frame_files(const fs::path& dir) {
  std::map<int, fs::path> files;
  const auto rank = [](const fs::path& p) {
    const auto e = p.extension();
    return e == ".obj" ? 0 : e == ".vtu" ? 1 : 2;
  };
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    const auto ext = entry.path().extension();
    if (name.rfind("frame_", 0) != 0 || !(ext == ".obj" || ext == ".vtu" || ext == ".ply")) continue;
    const std::string digits = entry.path().stem().string().substr(6);
    int k = 0;
    const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), k);
    if (r.ec != std::errc() || r.ptr != digits.data() + digits.size() || digits.empty()) continue;
    const auto [it, fresh] = files.emplace(k, entry.path());
    if (!fresh && rank(entry.path()) < rank(it->second)) it->second = entry.path();
  }
  return files;
}

// The frame file's points split into the scene's sheets; a file that does not fit its
// scene.json (another scene's frames in the folder) is refused.
template <class Real>
Frame read_back(const Scene& scene, const fs::path& file) {
  FramePoints<Real> points;
  try {
    points = read_frame<Real>(file);
  } catch (const std::runtime_error& e) {
    throw Failure{exit_bad_scene, e.what()};
  }
  std::vector<std::uint64_t> sizes;
  std::uint64_t total = 0;
  for (const auto& s : scene.sheets) {
    sizes.push_back(point_count(s.m, s.n));
    total += sizes.back();
  }
  const bool fits = points.sheet_sizes.empty() ? points.x.size() == total : points.sheet_sizes == sizes;
  if (!fits)
    throw Failure{exit_bad_scene, file.string() + ": holds " + std::to_string(points.x.size()) + " points in " +
                                      std::to_string(std::max<std::size_t>(1, points.sheet_sizes.size())) +
                                      " sheet(s), but " + scene.file + " has " + std::to_string(sizes.size()) +
                                      " sheet(s) of " + std::to_string(total) + " points"};
  Frame f;
  std::size_t at = 0;
  for (const std::uint64_t n : sizes) {
    f.x.emplace_back(points.x.begin() + at, points.x.begin() + at + n);
    f.y.emplace_back(points.y.begin() + at, points.y.begin() + at + n);
    f.z.emplace_back(points.z.begin() + at, points.z.begin() + at + n);
    at += n;
  }
  for (std::size_t p = 0; p < points.x.size(); ++p)
    if (!std::isfinite(points.x[p]) || !std::isfinite(points.y[p]) || !std::isfinite(points.z[p]))
      throw Failure{exit_bad_scene, file.string() + ": point " + std::to_string(p) + " is not finite"};
  return f;
}

render::Camera choose_camera(const Scene& scene, std::span<const render::SheetMesh> meshes, const std::string& spec,
                             double aspect) {
  render::Camera base;
  if (scene.camera) {
    base = {scene.camera->eye, scene.camera->target, scene.camera->up, scene.camera->fov_degrees};
    if (const std::string problem = render::validate(base); !problem.empty())
      throw Failure{exit_bad_scene, scene.file + ": camera: " + problem};
  } else {
    base = render::Camera::looking_at_bounds(render::scene_bounds(meshes, scene.obstacles), aspect);
  }
  if (spec.empty()) return base;
  try {
    return render::parse_camera(spec, base);
  } catch (const std::invalid_argument& e) {
    throw Failure{exit_usage, std::string("--camera: ") + e.what()};
  }
}

int render_or_throw(const RenderArgs& args, std::ostream& log) {
  const auto size = parse_size(args.size);
  if (!size) throw Failure{exit_usage, "--size: expected WxH with 1 to 8192 pixels per side, got \"" + args.size + "\""};
  const auto [width, height] = *size;
  if (const std::size_t n = std::max<std::size_t>(1, args.frames.size()); std::uint64_t(width) * n > 8192)
    throw Failure{exit_usage, "--size, --frame: " + std::to_string(n) + " panels of " + std::to_string(width) +
                                  " pixels are wider than 8192 pixels"};

  // Refuse an output nobody can write before spending time on the simulation.
  const fs::path out = args.output;
  const fs::path folder = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec))
    throw Failure{exit_write_failed, "cannot write " + out.string() + ": the folder " + folder.string() + " does not exist"};
  if (fs::is_directory(out, ec)) throw Failure{exit_write_failed, "cannot write " + out.string() + ": it is a folder"};
  std::string extension = out.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
  if (extension != ".png")  // r.jpg got PNG bytes under a JPEG name
    throw Failure{exit_usage, "-o " + out.string() + ": drape render writes PNG images; name the file .png"};

  const fs::path input = args.input;
  const bool from_folder = fs::is_directory(input, ec);
  Scene scene;
  try {
    if (from_folder && !fs::exists(input / "scene.json", ec))
      throw SceneError(input.string() + ": not an output folder of `drape run` (no scene.json in it)");
    scene = load_scene(from_folder ? input / "scene.json" : input);
  } catch (const SceneError& e) {
    throw Failure{exit_bad_scene, e.what()};
  }

  std::vector<int> wanted = args.frames;
  std::map<int, Frame> frames;
  const bool f32 = scene.precision == Precision::Float32;
  if (from_folder) {
    const auto files = frame_files(input);
    if (files.empty()) throw Failure{exit_bad_scene, input.string() + ": no frame files (frame_NNNNN.obj, .vtu or .ply)"};
    if (wanted.empty()) wanted.push_back(files.rbegin()->first);
    for (const int k : wanted) {
      const auto it = files.find(k);
      if (it == files.end())
        throw Failure{exit_usage, "--frame " + std::to_string(k) + ": " + input.string() + " has no such frame (it has " +
                                      std::to_string(files.size()) + " frames, " + std::to_string(files.begin()->first) +
                                      " to " + std::to_string(files.rbegin()->first) + ")"};
      frames[k] = f32 ? read_back<float>(scene, it->second) : read_back<double>(scene, it->second);
    }
  } else {
    if (wanted.empty()) wanted.push_back(scene.frames);
    for (const int k : wanted)
      if (k > scene.frames)
        throw Failure{exit_usage, "--frame " + std::to_string(k) + ": " + scene.file + " has frames 0 to " +
                                      std::to_string(scene.frames)};
    frames = f32 ? simulate<float>(scene, wanted) : simulate<double>(scene, wanted);
  }
  const int panels = int(wanted.size());

  // One camera for every panel, so the panels compare; the automatic one frames them all.
  std::vector<std::vector<render::SheetMesh>> meshes;
  std::vector<render::SheetMesh> all;
  for (const int k : wanted) {
    const Frame& f = frames.at(k);
    auto& panel = meshes.emplace_back();
    for (std::size_t s = 0; s < scene.sheets.size(); ++s)
      panel.push_back({scene.sheets[s].m, scene.sheets[s].n, f.x[s], f.y[s], f.z[s]});
    all.insert(all.end(), panel.begin(), panel.end());
  }
  const render::Camera camera = choose_camera(scene, all, args.camera, double(width) / height);

  render::RenderOptions options;
  options.opaque_sheets = !args.see_through;
  const bool shaded = args.style == "shaded";
  options.surface = *render::surface_kind_from_name(args.surface);  // checked by the option
  options.surface_samples = args.surface_samples > 0 ? args.surface_samples
                                                     : (options.surface == render::SurfaceKind::Grid ? 1 : 4);
  try {
    render::Image strip(width * panels, height, options.background);
    for (int p = 0; p < panels; ++p) {
      std::vector<ObstacleDef> obstacles;  // moving ones where they are at the panel's frame
      for (const ObstacleDef& o : scene.obstacles) obstacles.push_back(obstacle_at(o, wanted[p] * scene.frame_time()));
      const render::Image image = shaded ? render::render_shaded(meshes[p], obstacles, camera, width, height, options)
                                         : render::render_wireframe(meshes[p], obstacles, camera, width, height, options);
      for (int y = 0; y < height; ++y)
        std::copy_n(image.rgb.begin() + std::ptrdiff_t(y) * width * 3, width * 3,
                    strip.rgb.begin() + (std::ptrdiff_t(y) * width * panels + std::ptrdiff_t(p) * width) * 3);
      if (p > 0)  // a light rule between panels
        for (int y = 0; y < height; ++y) strip.set_pixel(p * width, y, {200, 200, 200});
    }
    render::write_png(strip, out.string());
  } catch (const std::invalid_argument& e) {
    throw Failure{exit_usage, e.what()};
  } catch (const std::runtime_error& e) {
    throw Failure{exit_write_failed, e.what()};
  }
  std::string list;
  for (const int k : wanted) list += (list.empty() ? "" : ",") + std::to_string(k);
  log << "drape: wrote " << out.string() << " (" << width * panels << "x" << height << ", frame" << (panels > 1 ? "s " : " ") << list << " of "
      << (from_folder ? input.string() : scene.file) << ", camera \"" << render::format_camera(camera) << "\")\n";
  return exit_ok;
}

}  // namespace

CLI::App* add_render_subcommand(CLI::App& app, RenderArgs& args) {
  CLI::App* render = app.add_subcommand(
      "render",
      "Draw one frame as a wireframe PNG, like the paper's figures, or as shaded surfaces (--style shaded): from a scene file (simulated up to the frame) "
      "or from an output folder of `drape run` (the frame's mesh read back)");
  render->add_option("SCENE_OR_OUTPUT", args.input, "Scene file (JSON), or a folder `drape run` wrote")->required();
  render->add_option("-o,--output", args.output, "The PNG to write (replaced atomically)")->required();
  render->add_option("--frame", args.frames,
                     "Frame to draw, 0 = initial state (default: the last); several, comma-separated, give a strip "
                     "of panels left to right, all seen by the same camera")
      ->delimiter(',')
      ->check(CLI::Range(0, 10000000));
  render->add_option("--camera", args.camera,
                     "Camera fields to change, e.g. \"eye=4,-3,2;target=0,0,0;up=0,0,1;fov=35\" (others keep the "
                     "scene's camera, or the automatic framing when the scene has none)");
  render->add_option("--size", args.size, "Size WxH in pixels of one panel (default 800x600)");
  render->add_flag("--see-through", args.see_through, "Draw lines behind sheets too (sheets are not opaque)");
  render->add_option("--style", args.style,
                     "wireframe (grid lines, like the paper's figures) or shaded (lit surfaces: the sheets' two sides "
                     "in two colours, obstacles solid)")
      ->check(CLI::IsMember({"wireframe", "shaded"}));
  render->add_option("--surface", args.surface,
                     "With --style shaded: the surface drawn over each sheet's grid: grid (its cells), bezier (the "
                     "paper's Bezier surface, bicubic pieces) or bspline (uniform bicubic B-spline)")
      ->check(CLI::IsMember({"grid", "bezier", "bspline"}));
  render->add_option("--surface-samples", args.surface_samples,
                     "With --style shaded: samples per grid cell along each side (default 1 for grid, 4 otherwise)")
      ->check(CLI::Range(1, 64));
  return render;
}

int render_command(const RenderArgs& args, std::ostream& log) {
  try {
    return render_or_throw(args, log);
  } catch (const Failure& f) {
    log << "drape: " << f.message << '\n';
    return f.code;
  }
}

}  // namespace drape::app
