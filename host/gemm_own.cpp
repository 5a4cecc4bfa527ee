// Our own GEMM engine: maps the four row-major transpose cases onto kernels/gemm.cl's tile kernel.
//
// The tile kernel wants its right operand contiguous along the output dimension it vectorises (q), and
// takes the left operand with any strides. Row-major C = op(A) op(B):
//   NN: L = A,  R = B,  D = C                 (B rows are contiguous along n)
//   TN: L = A^T (strided reads), R = B, D = C
//   TT: D = C^T = B_stored[N,K] A_stored[K,M]: L = B, R = A (A rows contiguous along m), C written transposed
//   NT: neither operand is contiguous along m or n (both run along k), so one is packed per K chunk with
//       the transpose kernel: the smaller of A and B, because packing costs its size per chunk.
// K is split into chunks of kc: the first chunk applies beta, the others accumulate (beta = 1). Chunks
// keep the L and R panels of one launch in cache; for NT they bound the scratch buffer.
#include <algorithm>
#include <climits>
#include <cstdint>
#include <string>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "host/launch.hpp"
#include "host/runtime.hpp"

namespace stylerf::host {
namespace {

int to_int(size_t v, const char* what) {
  if (v > static_cast<size_t>(INT_MAX)) throw Error(std::string("own GEMM: ") + what + " exceeds 2^31-1 elements");
  return static_cast<int>(v);
}

struct View {
  cl_mem mem;
  size_t off;
};

// One launch of the tile kernel: D[P,Q] = alpha L[P,K] R[K,Q] + beta D.
void tile_launch(const OwnGemmParams& p, int P, int Q, int K, float alpha, View L, int slp, int slk, View R,
                 int srk, float beta, View C, int scp, int scq) {
  OwnGemmParams q = p;
  // A row count below the tile height would compute clamped duplicate rows: shrink the tile instead
  // (e.g. the decoder's last conv has 3 output channels).
  if (P < q.mr) q.mr = P;
  const int nr = q.vw * q.nv;
  const size_t tiles_p = static_cast<size_t>((P + q.mr - 1) / q.mr);
  const size_t tiles_q = static_cast<size_t>(((Q + nr - 1) / nr + q.qt - 1) / q.qt);
  const size_t wg = std::min<size_t>(static_cast<size_t>(q.wg), tiles_p);
  launch_with_local("gemm", "gemm_tile", q.build_options(), Range(tiles_p, tiles_q), Range(wg, 1), P, Q, K, alpha,
                    L.mem, to_int(L.off, "offset"), slp, slk, R.mem, to_int(R.off, "offset"), srk, beta, C.mem,
                    to_int(C.off, "offset"), scp, scq);
}

// dst[c*ldd + r] = src[r*lds + c] for r < rows, c < cols.
void transpose_launch(int rows, int cols, View src, int lds, View dst, int ldd) {
  launch_with_local("gemm", "transpose_block8", "", Range((cols + 7) / 8, (rows + 7) / 8), Range(1, 1), rows, cols,
                    src.mem, to_int(src.off, "offset"), lds, dst.mem, to_int(dst.off, "offset"), ldd);
}

}  // namespace

void gemm_own_with(const OwnGemmParams& params, Trans ta, Trans tb, int M, int N, int K, float alpha, cl_mem A,
                   size_t a_offset, int lda, cl_mem B, size_t b_offset, int ldb, float beta, cl_mem C,
                   size_t c_offset, int ldc) {
  params.validate();
  if (M <= 0 || N <= 0) return;
  int kc = (params.kc > 0 && params.kc < K) ? params.kc : std::max(K, 0);
  // A small output has few tiles, so there is little panel reuse across work-items for K chunks to
  // protect, while every chunk costs a launch (~0.3 ms on PoCL). Weight gradients of small layers
  // (M, N <= 256, K = number of samples, up to millions) would otherwise take thousands of launches:
  // give them at most kMaxChunksSmallOutput chunks.
  constexpr int kMaxChunksSmallOutput = 8;
  if (static_cast<int64_t>(M) * N <= 256 * 256 && K > kMaxChunksSmallOutput * kc)
    kc = (K + kMaxChunksSmallOutput - 1) / kMaxChunksSmallOutput;
  const View a{A, a_offset}, b{B, b_offset}, c{C, c_offset};
  auto chunk_beta = [&](int k0) { return k0 == 0 ? beta : 1.0f; };

  if (K <= 0) {
    // No products: C = beta * C (BLAS semantics; alpha does not matter). K = 0 in the kernel does that.
    tile_launch(params, M, N, 0, alpha, a, 1, 1, b, 0, beta, c, ldc, 1);
    return;
  }

  if (ta == Trans::No && tb == Trans::Yes) {
    // NT: pack the smaller operand's chunk into [kc, M] or [kc, N] so it can be the vector operand.
    const bool pack_a = M <= N;
    const int rows = pack_a ? M : N;
    Buffer scratch(static_cast<size_t>(kc) * rows * sizeof(float), "own GEMM packing scratch");
    const View s{scratch.mem(), 0};
    for (int k0 = 0; k0 < K; k0 += kc) {
      const int kn = std::min(kc, K - k0);
      if (pack_a) {
        // C^T[N,M] = B[N,k] * A^T[k,M]
        transpose_launch(M, kn, View{A, a_offset + k0}, lda, s, M);
        tile_launch(params, N, M, kn, alpha, View{B, b_offset + k0}, ldb, 1, s, M, chunk_beta(k0), c, 1, ldc);
      } else {
        transpose_launch(N, kn, View{B, b_offset + k0}, ldb, s, N);
        tile_launch(params, M, N, kn, alpha, View{A, a_offset + k0}, lda, 1, s, N, chunk_beta(k0), c, ldc, 1);
      }
    }
    return;
  }

  for (int k0 = 0; k0 < K; k0 += kc) {
    const int kn = std::min(kc, K - k0);
    const size_t k0z = static_cast<size_t>(k0);
    if (ta == Trans::No && tb == Trans::No) {
      tile_launch(params, M, N, kn, alpha, View{A, a_offset + k0z}, lda, 1, View{B, b_offset + k0z * ldb}, ldb,
                  chunk_beta(k0), c, ldc, 1);
    } else if (ta == Trans::Yes && tb == Trans::No) {
      tile_launch(params, M, N, kn, alpha, View{A, a_offset + k0z * lda}, 1, lda, View{B, b_offset + k0z * ldb}, ldb,
                  chunk_beta(k0), c, ldc, 1);
    } else {  // TT
      tile_launch(params, N, M, kn, alpha, View{B, b_offset + k0z}, ldb, 1, View{A, a_offset + k0z * lda}, lda,
                  chunk_beta(k0), c, 1, ldc);
    }
  }
}

}  // namespace stylerf::host
