// STL, glTF and GLB through assimp: glTF checked whole first (gltf_check.cpp), the files assimp
// opens limited to regular files within the memory limit, every vertex checked finite before any
// post-processing; and written through an IOSystem that fails the export on any short write.
#include "mesh_impl.hpp"

#include "csrbf/io/controls.hpp"
#include "text.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "gltf_check.hpp"

#include <assimp/DefaultIOSystem.h>
#include <assimp/Exporter.hpp>
#include <assimp/IOStream.hpp>
#include <assimp/IOSystem.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

namespace fs = std::filesystem;

namespace csrbf::io {

namespace {

/// assimp reads the files a glTF names (its buffers, images) by itself: only regular files, and
/// all of them together within the memory limit.
class LimitedIOSystem : public Assimp::DefaultIOSystem {
 public:
  explicit LimitedIOSystem(double max_bytes) : left_(max_bytes) {}
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    std::error_code ec;
    const auto st = fs::status(file, ec);
    if (st.type() != fs::file_type::regular) {
      error_ = std::string("'") + file + "' is not a regular file";
      return nullptr;
    }
    left_ -= double(fs::file_size(file, ec));
    if (left_ < 0) {
      error_ = std::string("'") + file + "' takes the files read past the memory limit (--memory-limit)";
      return nullptr;
    }
    return DefaultIOSystem::Open(file, mode);
  }
  const std::string& error() const { return error_; }

 private:
  double left_;
  std::string error_;
};

}  // namespace

void MeshDocument::Impl::load_assimp(double max_bytes) {
  if (format == MeshFormat::Gltf || format == MeshFormat::Glb)
    detail::check_gltf(path, format == MeshFormat::Glb, max_bytes);
  importer = std::make_unique<Assimp::Importer>();
  auto* io = new LimitedIOSystem(max_bytes);  // owned by the importer
  importer->SetIOHandler(io);
  unsigned flags = aiProcess_PreTransformVertices | aiProcess_ValidateDataStructure;
  // STL repeats every vertex for each facet with the facet's normal: drop the normals so that the
  // copies of one vertex are joined (they are recomputed on output).
  if (format == MeshFormat::Stl) flags |= aiProcess_DropNormals | aiProcess_JoinIdenticalVertices;
  // Read first without post-processing, so that a non-finite vertex is found before joining or
  // cleaning steps can drop or merge it.
  const aiScene* raw = importer->ReadFile(path.string(), aiProcess_ValidateDataStructure);
  if (!raw)
    throw FileError(path.string() + ": cannot read mesh: " +
                    (io->error().empty() ? std::string(importer->GetErrorString()) : io->error()));
  for (unsigned m = 0; m < raw->mNumMeshes; ++m)
    for (unsigned v = 0; v < raw->mMeshes[m]->mNumVertices; ++v) {
      const aiVector3D& p = raw->mMeshes[m]->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw FileError(path.string() + ": mesh " + std::to_string(m) + " vertex " + std::to_string(v) +
                        " is not finite (" + format_number(p.x) + " " + format_number(p.y) + " " + format_number(p.z) +
                        ")");
    }
  const aiScene* scene = importer->ApplyPostProcessing(flags & ~unsigned(aiProcess_ValidateDataStructure));
  if (!scene) throw FileError(path.string() + ": cannot read mesh: " + importer->GetErrorString());
  if (scene->mNumMeshes == 0) throw FileError(path.string() + ": the file holds no mesh");
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    const auto base = std::uint32_t(positions.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const Vec3 p(mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z);
      // assimp passes NaN through, and a node's scale of 1e39 overflows single precision.
      if (!p.allFinite())
        throw FileError(path.string() + ": mesh " + std::to_string(m) + " vertex " + std::to_string(v) +
                        " is not finite (" + format_number(p.x()) + " " + format_number(p.y()) + " " +
                        format_number(p.z()) + ")");
      positions.push_back(p);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices < 3) continue;
      std::vector<std::uint32_t> out(face.mIndices, face.mIndices + face.mNumIndices);
      for (auto& i : out) i += base;
      faces.push_back(std::move(out));
    }
    has_normals = has_normals || mesh->mNormals != nullptr;
  }
}

namespace {

std::unique_ptr<aiScene> make_scene(const std::vector<Vec3>& p, const PolygonList& faces, bool triangulate) {
  auto scene = std::make_unique<aiScene>();
  scene->mRootNode = new aiNode();
  scene->mRootNode->mNumMeshes = 1;
  scene->mRootNode->mMeshes = new unsigned[1]{0};
  scene->mNumMaterials = 1;
  scene->mMaterials = new aiMaterial* [1] { new aiMaterial() };
  auto* mesh = new aiMesh();
  scene->mNumMeshes = 1;
  scene->mMeshes = new aiMesh* [1] { mesh };
  mesh->mMaterialIndex = 0;
  mesh->mNumVertices = unsigned(p.size());
  mesh->mVertices = new aiVector3D[p.size()];
  for (std::size_t i = 0; i < p.size(); ++i)
    mesh->mVertices[i] = aiVector3D(ai_real(p[i].x()), ai_real(p[i].y()), ai_real(p[i].z()));
  PolygonList polys;
  for (const auto& f : faces) {
    if (triangulate && f.size() > 3)
      for (std::size_t k = 1; k + 1 < f.size(); ++k) polys.push_back({f[0], f[k], f[k + 1]});
    else
      polys.push_back(f);
  }
  mesh->mNumFaces = unsigned(polys.size());
  mesh->mFaces = new aiFace[polys.size()];
  bool poly = false;
  for (std::size_t i = 0; i < polys.size(); ++i) {
    mesh->mFaces[i].mNumIndices = unsigned(polys[i].size());
    mesh->mFaces[i].mIndices = new unsigned[polys[i].size()];
    std::copy(polys[i].begin(), polys[i].end(), mesh->mFaces[i].mIndices);
    poly = poly || polys[i].size() > 3;
  }
  mesh->mPrimitiveTypes = aiPrimitiveType_TRIANGLE | (poly ? aiPrimitiveType_POLYGON : 0);
  return scene;
}

const char* assimp_export_id(MeshFormat f) {
  switch (f) {
    case MeshFormat::Stl:
      return "stlb";
    case MeshFormat::Gltf:
      return "gltf2";
    case MeshFormat::Glb:
      return "glb2";
    default:
      return nullptr;
  }
}

/// assimp's exporters do not check their writes: this file system records every short write, and
/// every failed flush or close, so that a full disk or a file size limit fails the export.
class CheckedIOSystem : public Assimp::IOSystem {
 public:
  class Stream : public Assimp::IOStream {
   public:
    Stream(std::FILE* f, CheckedIOSystem& sys, std::string name) : f_(f), sys_(sys), name_(std::move(name)) {}
    ~Stream() override {
      if (std::fflush(f_) != 0) sys_.fail(name_, errno);
      if (std::ferror(f_)) sys_.fail(name_, errno ? errno : EIO);
      if (std::fclose(f_) != 0) sys_.fail(name_, errno);
    }
    size_t Read(void* buf, size_t size, size_t count) override { return std::fread(buf, size, count, f_); }
    size_t Write(const void* buf, size_t size, size_t count) override {
      const size_t n = std::fwrite(buf, size, count, f_);
      if (n != count) sys_.fail(name_, errno);
      return n;
    }
    aiReturn Seek(size_t offset, aiOrigin origin) override {
      const int w = origin == aiOrigin_SET ? SEEK_SET : origin == aiOrigin_CUR ? SEEK_CUR : SEEK_END;
      return std::fseek(f_, long(offset), w) == 0 ? aiReturn_SUCCESS : aiReturn_FAILURE;
    }
    size_t Tell() const override { return size_t(std::ftell(f_)); }
    size_t FileSize() const override {
      const long here = std::ftell(f_);
      std::fseek(f_, 0, SEEK_END);
      const long end = std::ftell(f_);
      std::fseek(f_, here, SEEK_SET);
      return size_t(end);
    }
    void Flush() override {
      if (std::fflush(f_) != 0) sys_.fail(name_, errno);
    }

   private:
    std::FILE* f_;
    CheckedIOSystem& sys_;
    std::string name_;
  };

  bool Exists(const char* file) const override { return fs::exists(file); }
  char getOsSeparator() const override { return '/'; }
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    std::FILE* f = std::fopen(file, mode);
    if (!f) {
      fail(file, errno);
      return nullptr;
    }
    return new Stream(f, *this, fs::path(file).filename().string());
  }
  void Close(Assimp::IOStream* s) override { delete s; }

  void fail(const std::string& name, int err) {
    if (error_.empty())
      error_ = "writing '" + name + "' failed: " + std::strerror(err ? err : EIO) + " (disk full or file size limit?)";
  }
  const std::string& error() const { return error_; }

 private:
  std::string error_;
};

void export_scene(const aiScene* scene, const fs::path& out, MeshFormat f) {
  const char* id = assimp_export_id(f);
  write_atomically_via_folder(out, [&](const fs::path& tmp) {
    Assimp::Exporter exporter;
    auto* io = new CheckedIOSystem;  // owned by the exporter
    exporter.SetIOHandler(io);
    const aiReturn r = exporter.Export(scene, id, tmp.string());
    if (!io->error().empty()) throw FileError("cannot write '" + out.string() + "': " + io->error());
    if (r != AI_SUCCESS) {
      const std::string why = exporter.GetErrorString();
      throw FileError("cannot write '" + out.string() + "': " + format_name(f) + " export failed" +
                      (why.empty() ? std::string(" (assimp gave no reason)") : ": " + why));
    }
  });
}

}  // namespace

void MeshDocument::Impl::save_generic(const fs::path& out, MeshFormat f) const {
  // OFF's and ASCII PLY's body: a line "x y z" a vertex, then "count i j k ..." a polygon.
  const auto points_and_polygons = [&](std::ostream& os) {
    for (const auto& p : positions)
      os << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
    for (const auto& face : faces) {
      os << face.size();
      for (auto v : face) os << ' ' << v;
      os << '\n';
    }
  };
  switch (f) {
    case MeshFormat::Obj:
      write_atomically(out, [&](std::ostream& os) {
        os << "# written by csrbf\n";
        for (const auto& p : positions)
          os << "v " << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
        for (const auto& face : faces) {
          os << 'f';
          for (auto v : face) os << ' ' << v + 1;
          os << '\n';
        }
      });
      return;
    case MeshFormat::Off:
      write_atomically(out, [&](std::ostream& os) {
        os << "OFF\n" << positions.size() << ' ' << faces.size() << " 0\n";
        points_and_polygons(os);
      });
      return;
    case MeshFormat::Ply:
      write_atomically(out, [&](std::ostream& os) {
        os << "ply\nformat ascii 1.0\ncomment written by csrbf\nelement vertex " << positions.size()
           << "\nproperty double x\nproperty double y\nproperty double z\nelement face " << faces.size()
           << "\nproperty list uchar int vertex_indices\nend_header\n";
        points_and_polygons(os);
      });
      return;
    case MeshFormat::Xyz:
      write_atomically(out, [&](std::ostream& os) {
        for (const auto& p : positions)
          os << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
      });
      return;
    case MeshFormat::Stl:
    case MeshFormat::Gltf:
    case MeshFormat::Glb: {
      if (faces.empty())
        throw FileError("cannot write '" + out.string() + "': " + format_name(f) +
                        " needs faces and the mesh has none");
      const auto scene = make_scene(positions, faces, f == MeshFormat::Stl);
      export_scene(scene.get(), out, f);
      return;
    }
    case MeshFormat::Assimp:
      break;
  }
  throw FileError("cannot write '" + out.string() + "': unknown output format '" + out.extension().string() +
                  "' (use .obj, .ply, .off, .xyz, .stl, .gltf or .glb)");
}

bool MeshDocument::Impl::save_read_scene(const fs::path& path, MeshFormat out) const {
  if (!importer || !assimp_export_id(out)) return false;
  auto* scene = const_cast<aiScene*>(importer->GetScene());
  std::size_t base = 0;
  const auto vn = vertex_normals();
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    aiMesh* mesh = scene->mMeshes[m];
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const Vec3& p = positions[base + v];
      mesh->mVertices[v] = aiVector3D(ai_real(p.x()), ai_real(p.y()), ai_real(p.z()));
      if (mesh->mNormals)
        mesh->mNormals[v] = aiVector3D(ai_real(vn[base + v].x()), ai_real(vn[base + v].y()), ai_real(vn[base + v].z()));
    }
    base += mesh->mNumVertices;
  }
  export_scene(scene, path, out);
  return true;
}

}  // namespace csrbf::io
