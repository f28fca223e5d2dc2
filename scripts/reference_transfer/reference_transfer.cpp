// A reference deformation transfer in C++ with Eigen, the yardstick scripts/bench_reference_transfer.py
// times Shapesmith's transfer against. It does what pmp-library's DeformationTransfer does
// (Sumner & Popovic 2004 in the gradient form of Botsch et al. 2006):
//
//   once per pair of neutrals: the target's cotangent Laplacian L = sum_t area_t G_t^T G_t
//   (G_t the gradient operator of the target's rest triangle) and each source rest triangle's
//   inverse edge frame V^{-1} (S&P Eq. 3, fourth vertex n / sqrt|n|);
//   per shape: lock the vertices the source shape does not move, take each moving source
//   triangle's deformation gradient S_t = V~ V^{-1} (S&P Eq. 1), the target Laplacians
//   b_i = sum_t area_t S_t grad phi_i (the divergence of the transferred gradients), assemble
//   L on the free vertices, factorise it afresh with Eigen's SimplicialLDLT (AMD order) and
//   solve L_FF x_F = b_F - L_FL x_L for the three coordinates, as pmp does per transfer.
//
// So that its deltas can be checked against Shapesmith's plain transfer (virtual edges and
// the collision pass off, no rotation alignment) it follows that transfer's choices too: a
// vertex is locked when it moves less than 1e-4 of the shape's largest move, a shape moving
// less than 1e-6 of the template's diagonal is left at zero, and a piece with no locked vertex
// is pinned at its first moving vertex, then translated so that its mean delta is the source
// piece's times the pieces' RMS radius ratio (without a pin its system would be singular).
//
//   reference_transfer DIR OUT.f32
//
// reads DIR/source.f32, DIR/target.f32, DIR/deltas.f32 (K x N x 3 float32) and
// DIR/triangles.u32 (T x 3 uint32), writes the K x N x 3 float32 target deltas to OUT.f32 and
// prints {"setup": s, "solves": s, "seconds": s} (wall seconds, reading and writing excluded),
// single-threaded as pmp is.

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Triangle = std::array<uint32_t, 3>;

namespace {

constexpr double STATIC_FRACTION = 1e-4;  // Shapesmith's TransferParams::static_fraction
constexpr double INERT_FRACTION = 1e-6;   // Shapesmith's rig::INERT_FRACTION

template <typename T>
std::vector<T> read_raw(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw std::runtime_error("cannot read " + path);
    const std::streamsize bytes = in.tellg();
    in.seekg(0);
    std::vector<T> out(static_cast<size_t>(bytes) / sizeof(T));
    in.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(out.size() * sizeof(T)));
    return out;
}

std::vector<Vec3> read_points(const std::string& path) {
    const std::vector<float> raw = read_raw<float>(path);
    std::vector<Vec3> out(raw.size() / 3);
    for (size_t i = 0; i < out.size(); ++i) out[i] = Vec3(raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]);
    return out;
}

// Columns v2 - v1, v3 - v1, n / sqrt|n| (S&P's fourth vertex).
Mat3 edge_frame(const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 e1 = b - a, e2 = c - a;
    Vec3 n = e1.cross(e2);
    const double len = n.norm();
    if (len > 0.0) n /= std::sqrt(len);
    Mat3 m;
    m.col(0) = e1;
    m.col(1) = e2;
    m.col(2) = n;
    return m;
}

// The gradients of the three hat functions of a triangle and its area.
struct HatGradients {
    double area;
    Vec3 gradient[3];
};

HatGradients hat_gradients(const Vec3 p[3]) {
    const Vec3 n = (p[1] - p[0]).cross(p[2] - p[0]);
    const double twice_area = n.norm();
    if (!(twice_area > 0.0)) throw std::runtime_error("a target triangle is degenerate");
    const Vec3 unit = n / twice_area;
    HatGradients h{0.5 * twice_area, {}};
    for (int i = 0; i < 3; ++i) h.gradient[i] = unit.cross(p[(i + 2) % 3] - p[(i + 1) % 3]) / twice_area;
    return h;
}

// Connected pieces over the triangles' edges (union-find); labels numbered by first vertex.
std::vector<uint32_t> pieces(size_t n, const std::vector<Triangle>& triangles, size_t& count) {
    std::vector<uint32_t> parent(n);
    for (size_t v = 0; v < n; ++v) parent[v] = static_cast<uint32_t>(v);
    auto find = [&](uint32_t v) {
        while (parent[v] != v) v = parent[v] = parent[parent[v]];
        return v;
    };
    for (const Triangle& t : triangles) {
        for (int e = 0; e < 2; ++e) {
            const uint32_t a = find(t[e]), b = find(t[e + 1]);
            if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
    }
    std::vector<uint32_t> label(n, UINT32_MAX);
    count = 0;
    for (size_t v = 0; v < n; ++v) {
        const uint32_t root = find(static_cast<uint32_t>(v));
        if (label[root] == UINT32_MAX) label[root] = static_cast<uint32_t>(count++);
        label[v] = label[root];
    }
    return label;
}

// Per piece, the target's RMS radius over the source's (1 where the source has no extent).
std::vector<double> piece_scales(const std::vector<Vec3>& source, const std::vector<Vec3>& target, const std::vector<uint32_t>& piece, size_t count) {
    std::vector<Vec3> cs(count, Vec3::Zero()), ct(count, Vec3::Zero());
    std::vector<double> members(count, 0.0), ss(count, 0.0), st(count, 0.0), out(count, 1.0);
    for (size_t v = 0; v < source.size(); ++v) {
        cs[piece[v]] += source[v];
        ct[piece[v]] += target[v];
        members[piece[v]] += 1.0;
    }
    for (size_t p = 0; p < count; ++p) cs[p] /= members[p], ct[p] /= members[p];
    for (size_t v = 0; v < source.size(); ++v) {
        ss[piece[v]] += (source[v] - cs[piece[v]]).squaredNorm();
        st[piece[v]] += (target[v] - ct[piece[v]]).squaredNorm();
    }
    for (size_t p = 0; p < count; ++p) {
        const double s = std::sqrt(ss[p] / members[p]), t = std::sqrt(st[p] / members[p]);
        if (s > 0.0 && std::isfinite(t)) out[p] = t / s;
    }
    return out;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::cerr << "usage: reference_transfer DIR OUT.f32\n";
        return 2;
    }
    const std::string dir = argv[1];
    std::vector<Vec3> source, target, deltas;
    std::vector<Triangle> triangles;
    try {
        source = read_points(dir + "/source.f32");
        target = read_points(dir + "/target.f32");
        deltas = read_points(dir + "/deltas.f32");
        const std::vector<uint32_t> raw = read_raw<uint32_t>(dir + "/triangles.u32");
        triangles.resize(raw.size() / 3);
        for (size_t t = 0; t < triangles.size(); ++t) triangles[t] = {raw[3 * t], raw[3 * t + 1], raw[3 * t + 2]};
    } catch (const std::exception& e) {
        std::cerr << e.what() << "\n";
        return 2;
    }
    const size_t n = source.size();
    if (n == 0 || target.size() != n || deltas.size() % n != 0) {
        std::cerr << "the template, target and deltas disagree in vertex count\n";
        return 2;
    }
    const size_t shapes = deltas.size() / n;

    // Once per pair of neutrals: the Laplacian, the source frames' inverses, the pieces.
    const auto started = std::chrono::steady_clock::now();
    std::vector<HatGradients> operators(triangles.size());
    std::vector<Mat3> rest_inverse(triangles.size());
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(9 * triangles.size());
    try {
        for (size_t t = 0; t < triangles.size(); ++t) {
            const Triangle& tri = triangles[t];
            const Vec3 p[3] = {target[tri[0]], target[tri[1]], target[tri[2]]};
            operators[t] = hat_gradients(p);
            const Mat3 frame = edge_frame(source[tri[0]], source[tri[1]], source[tri[2]]);
            if (frame.determinant() == 0.0) throw std::runtime_error("a source triangle is degenerate");
            rest_inverse[t] = frame.inverse();
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                    entries.emplace_back(tri[a], tri[b], operators[t].area * operators[t].gradient[a].dot(operators[t].gradient[b]));
        }
    } catch (const std::exception& e) {
        std::cerr << e.what() << "\n";
        return 2;
    }
    Eigen::SparseMatrix<double> laplacian(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    laplacian.setFromTriplets(entries.begin(), entries.end());
    size_t n_pieces = 0;
    const std::vector<uint32_t> piece = pieces(n, triangles, n_pieces);
    const std::vector<double> scale = piece_scales(source, target, piece, n_pieces);
    Vec3 low = source[0], high = source[0];
    for (const Vec3& p : source) low = low.cwiseMin(p), high = high.cwiseMax(p);
    const double diagonal = (high - low).norm();
    const double setup = seconds_since(started);

    std::vector<float> out(3 * n * shapes, 0.0f);
    std::vector<int> free_index(n);
    for (size_t k = 0; k < shapes; ++k) {
        const Vec3* delta = &deltas[k * n];
        double largest = 0.0;
        for (size_t v = 0; v < n; ++v) largest = std::max(largest, delta[v].norm());
        if (largest <= INERT_FRACTION * diagonal) continue;
        // Lock what does not move; pin one vertex of each piece that has nothing locked.
        std::vector<bool> moving(n), anchored(n_pieces, false), pinned(n_pieces, false);
        for (size_t v = 0; v < n; ++v) {
            moving[v] = delta[v].norm() >= STATIC_FRACTION * largest;
            if (!moving[v]) anchored[piece[v]] = true;
        }
        int n_free = 0;
        for (size_t v = 0; v < n; ++v) {
            free_index[v] = -1;
            if (!moving[v]) continue;
            if (!anchored[piece[v]] && !pinned[piece[v]]) {
                pinned[piece[v]] = true;
                continue;
            }
            free_index[v] = n_free++;
        }
        std::vector<Vec3> position(target);
        if (n_free > 0) {
            // The target Laplacians: divergence of the transferred gradients S_t.
            Eigen::MatrixX3d rhs = Eigen::MatrixX3d::Zero(n_free, 3);
            for (size_t t = 0; t < triangles.size(); ++t) {
                const Triangle& tri = triangles[t];
                if (free_index[tri[0]] < 0 && free_index[tri[1]] < 0 && free_index[tri[2]] < 0) continue;
                const Mat3 gradient = edge_frame(source[tri[0]] + delta[tri[0]], source[tri[1]] + delta[tri[1]], source[tri[2]] + delta[tri[2]]) * rest_inverse[t];
                for (int a = 0; a < 3; ++a) {
                    const int row = free_index[tri[a]];
                    if (row >= 0) rhs.row(row) += (operators[t].area * (gradient * operators[t].gradient[a])).transpose();
                }
            }
            // L on the free vertices; the locked ones move to the right-hand side.
            std::vector<Eigen::Triplet<double>> block;
            block.reserve(laplacian.nonZeros());
            for (Eigen::Index c = 0; c < laplacian.outerSize(); ++c) {
                const int column = free_index[c];
                for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, c); it; ++it) {
                    const int row = free_index[it.row()];
                    if (row < 0) continue;
                    if (column >= 0) {
                        block.emplace_back(row, column, it.value());
                    } else {
                        rhs.row(row) -= it.value() * target[c].transpose();
                    }
                }
            }
            Eigen::SparseMatrix<double> system(n_free, n_free);
            system.setFromTriplets(block.begin(), block.end());
            Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
            solver.compute(system);
            if (solver.info() != Eigen::Success) {
                std::cerr << "shape " << k << ": the system could not be factorised\n";
                return 1;
            }
            const Eigen::MatrixX3d solved = solver.solve(rhs);
            for (size_t v = 0; v < n; ++v)
                if (free_index[v] >= 0) position[v] = solved.row(free_index[v]).transpose();
        }
        std::vector<Vec3> result(n);
        for (size_t v = 0; v < n; ++v) result[v] = position[v] - target[v];
        // Floating pieces: the source piece's mean motion, scaled.
        std::vector<Vec3> solved_sum(n_pieces, Vec3::Zero()), source_sum(n_pieces, Vec3::Zero());
        std::vector<double> members(n_pieces, 0.0);
        for (size_t v = 0; v < n; ++v) {
            if (!pinned[piece[v]]) continue;
            solved_sum[piece[v]] += result[v];
            source_sum[piece[v]] += delta[v];
            members[piece[v]] += 1.0;
        }
        for (size_t v = 0; v < n; ++v) {
            const uint32_t p = piece[v];
            if (pinned[p]) result[v] += (source_sum[p] * scale[p] - solved_sum[p]) / members[p];
            for (int c = 0; c < 3; ++c) out[3 * (k * n + v) + c] = static_cast<float>(result[v][c]);
        }
    }
    const double total = seconds_since(started);

    std::ofstream file(argv[2], std::ios::binary);
    file.write(reinterpret_cast<const char*>(out.data()), static_cast<std::streamsize>(out.size() * sizeof(float)));
    if (!file) {
        std::cerr << "cannot write " << argv[2] << "\n";
        return 2;
    }
    std::printf("{\"setup\": %.6f, \"solves\": %.6f, \"seconds\": %.6f}\n", setup, total - setup, total);
    return 0;
}
