// vdb_adaptive.cpp - OpenVDB's adaptive volumeToMesh on a raw int16 volume, beside surfd's merge=pieces
// (issue 45). usage: vdb_adaptive RAW NX NY NZ ISO SX SY SZ PAD THREADS OUT_PREFIX A1 [A2 ...]
// Outside the volume is the background PAD (as the other benches pad it, so the surface closes):
// the samples copied into a FloatGrid (voxel size SX SY SZ), then meshed at each adaptivity
// A (0: every voxel; 1: the most merging), quads cut into two triangles, written as
// OUT_PREFIX_A.stl. Prints JSON: per adaptivity the best of 3 volumeToMesh times (ms) and the
// triangles. Build: g++ -O2 -std=c++17 vdb_adaptive.cpp -lopenvdb -ltbb -lImath-3_1 (Debian libopenvdb-dev,
// libboost-dev, libtbb-dev).
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

int main(int argc, char **argv)
{
    if (argc < 13) {
        std::fprintf(stderr, "usage: vdb_adaptive RAW NX NY NZ ISO SX SY SZ PAD THREADS OUT_PREFIX A1 [A2 ...]\n");
        return 2;
    }
    int n[3] = {std::atoi(argv[2]), std::atoi(argv[3]), std::atoi(argv[4])};
    double iso = std::atof(argv[5]), sp[3] = {std::atof(argv[6]), std::atof(argv[7]), std::atof(argv[8])};
    float pad = (float)std::atof(argv[9]);
    int threads = std::atoi(argv[10]);
    const char *prefix = argv[11];
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    openvdb::initialize();
    std::vector<int16_t> raw((size_t)n[0] * n[1] * n[2]);
    FILE *f = std::fopen(argv[1], "rb");
    if (!f || std::fread(raw.data(), 2, raw.size(), f) != raw.size()) {
        std::fprintf(stderr, "cannot read %s\n", argv[1]);
        return 1;
    }
    std::fclose(f);
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(pad);
    auto xf = openvdb::math::Transform::createLinearTransform();
    xf->preScale(openvdb::Vec3d(sp[0], sp[1], sp[2]));
    grid->setTransform(xf);
    {
        auto acc = grid->getAccessor();
        for (int z = 0; z < n[2]; z++)
            for (int y = 0; y < n[1]; y++)
                for (int x = 0; x < n[0]; x++) {
                    float v = raw[(size_t)x + (size_t)n[0] * ((size_t)y + (size_t)n[1] * z)];
                    if (v != pad)
                        acc.setValue(openvdb::Coord(x, y, z), v);
                }
    }
    std::printf("{\"runs\": [");
    for (int k = 12; k < argc; k++) {
        double a = std::atof(argv[k]), best = 1e300;
        std::vector<openvdb::Vec3s> pts;
        std::vector<openvdb::Vec3I> tris;
        std::vector<openvdb::Vec4I> quads;
        for (int r = 0; r < 3; r++) {
            pts.clear(), tris.clear(), quads.clear();
            auto t0 = std::chrono::steady_clock::now();
            openvdb::tools::volumeToMesh(*grid, pts, tris, quads, iso, a);
            double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
            best = ms < best ? ms : best;
        }
        size_t nt = tris.size() + 2 * quads.size();
        char name[512];
        std::snprintf(name, sizeof name, "%s_%g.stl", prefix, a);
        FILE *o = std::fopen(name, "wb");
        if (!o)
            return 1;
        char header[80] = {0};
        uint32_t count = (uint32_t)nt;
        std::fwrite(header, 1, 80, o);
        std::fwrite(&count, 4, 1, o);
        auto put = [&](unsigned i, unsigned j, unsigned l) {
            float b[12] = {0, 0, 0};
            unsigned id[3] = {i, j, l};
            for (int c = 0; c < 3; c++)
                for (int d = 0; d < 3; d++)
                    b[3 + 3 * c + d] = pts[id[c]][d];
            uint16_t attr = 0;
            std::fwrite(b, 4, 12, o);
            std::fwrite(&attr, 2, 1, o);
        };
        for (auto &t : tris)
            put(t[0], t[1], t[2]);
        for (auto &q : quads)
            put(q[0], q[1], q[2]), put(q[0], q[2], q[3]);
        std::fclose(o);
        std::printf("%s{\"adaptivity\": %g, \"ms\": %.3f, \"triangles\": %zu, \"stl\": \"%s\"}", k > 12 ? ", " : "", a, best, nt,
                    name);
    }
    std::printf("]}\n");
    return 0;
}
