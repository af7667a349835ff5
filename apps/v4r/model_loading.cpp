// v4r - robust model-based object tracking. MIT licence.
// Models as every subcommand reads them: built-in names, .cao files and meshes, in the user's units.
#include <cctype>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "app.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/model/model_colour.hpp"
#include "v4r/model/model_scale.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::app {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::optional<std::string> builtin_model_text(const std::string& name) {
  if (name == "box") return synth::box_cao();
  if (name == "ship" || name == "ship_mockup") return synth::ship_mockup_cao();
  if (name == "flange") return synth::flange_cao();
  if (name == "section" || name == "ship_section") return synth::ship_section_cao();
  if (name == "sponge") return synth::sponge_cao();
  return std::nullopt;
}

bool is_mesh_path(const std::string& path) {
  const std::string ext = lower(fs::path(path).extension().string());
  return ext == ".obj" || ext == ".ply" || ext == ".stl" || ext == ".off" || ext == ".dae" || ext == ".fbx" ||
         ext == ".3ds" || ext == ".gltf" || ext == ".glb";
}

Expected<double> units_scale(const std::string& units) {
  const std::string u = lower(units);
  if (u == "m") return 1.0;
  if (u == "cm") return 0.01;
  if (u == "mm") return 0.001;
  return make_error("--model-units", 0, 0, fmt::format("unknown unit '{}' (mm, cm or m)", units));
}

std::shared_ptr<const model::Model> with_colour(std::shared_ptr<const model::Model> m, const std::optional<Eigen::Vector3f>& colour) {
  if (!colour || !m) return m;
  return std::make_shared<const model::Model>(model::with_face_colour(*m, *colour));
}

Expected<double> model_scale(const ModelUnitsArgs& a) {
  if (a.units.empty()) return a.mesh_scale;
  auto s = units_scale(a.units);
  if (!s) return s;
  if (a.mesh_scale_given && a.mesh_scale != *s)
    return make_error(fmt::format("--model-units {} means --mesh-scale {}, but --mesh-scale {} is given", a.units, *s,
                                  a.mesh_scale));
  return *s;
}

Expected<std::shared_ptr<const model::Model>> load_model(const std::string& path, double mesh_scale,
                                                         const model::CaoReadOptions& cao, std::vector<Error>* warnings) {
  Expected<model::Model> m = make_error("");
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    const std::optional<std::string> text = builtin_model_text(path);
    if (!text) return make_error(path, 0, 0, "model file not found (built-in models: box, ship, flange, section, sponge)");
    m = model::parse_cao(*text, path, cao, warnings);
  } else if (fs::is_directory(path, ec)) {
    return make_error(path, 0, 0, "is a directory, not a model file");
  } else if (lower(fs::path(path).extension().string()) == ".cao") {
    m = model::load_cao(path, cao, warnings);
  } else if (is_mesh_path(path)) {
    model::MeshImportOptions mo;
    mo.scale = mesh_scale;
    m = model::load_mesh(path, mo);
    mesh_scale = 1.0;  // applied on import
  } else {
    return make_error(path, 0, 0,
                      fmt::format("unsupported model format '{}' (supported: .cao, .obj, .ply, .stl)",
                                  fs::path(path).extension().string()));
  }
  if (!m) return m.error();
  if (m->lines().empty() && m->arcs().empty()) return make_error(path, 0, 0, "model has no edges to track");
  if (mesh_scale != 1.0) {
    auto s = model::scaled(*m, mesh_scale);
    if (!s) {
      Error e = s.error();
      e.file = path;
      return Unexpected{std::move(e)};
    }
    m = std::move(*s);
  }
  return std::shared_ptr<const model::Model>(std::make_shared<model::Model>(std::move(*m)));
}

}  // namespace v4r::app
