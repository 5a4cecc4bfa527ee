// The indicator of a 3D region at the samples of a ray (lib/model/region.hpp): 1 inside, 0 outside.
// Rendered with the scene's own weights it gives a soft per-pixel mask that agrees across views.
//
// pos [K,3] is normalised to the scene box ([-1,1]^3, as the ray marcher writes it); the ray-space point is
// p = lo + (pos + 1) / 2 * (hi - lo). NDC scenes map p back to the world (inverse of lib/scene/rays.hpp):
//   z = 2 near / (p.z - 1),  x = -p.x z sx,  y = -p.y z sy   (sx = W / 2fx, sy = H / 2fy)
// p.z >= 1 is the far end, infinitely far: such points lie in no box or sphere, and in a slab only when its
// far end is itself +infinity (decided explicitly: 2 near / (p.z - 1) would give +inf or NaN there).
//
// geo: lo.xyz, hi.xyz, sx, sy, near (11 floats). region: box lo.xyz hi.xyz | sphere c.xyz r |
// slab c.xyz axis.xyz d0 d1 (distance along the unit axis from c).
#define REGION_BOX 0
#define REGION_SPHERE 1
#define REGION_SLAB 2

kernel void region_indicator(global const float* pos, global float* out, int n, global const float* geo,
                             int ndc, int kind, global const float* region) {
  const int i = get_global_id(0);
  if (i >= n) return;
  float3 p;
  p.x = geo[0] + 0.5f * (pos[3 * i + 0] + 1.0f) * (geo[3] - geo[0]);
  p.y = geo[1] + 0.5f * (pos[3 * i + 1] + 1.0f) * (geo[4] - geo[1]);
  p.z = geo[2] + 0.5f * (pos[3 * i + 2] + 1.0f) * (geo[5] - geo[2]);
  if (ndc && p.z >= 1.0f) {
    out[i] = (kind == REGION_SLAB && isinf(region[7]) && region[7] > 0.0f) ? 1.0f : 0.0f;
    return;
  }
  if (ndc) {
    const float z = 2.0f * geo[8] / (p.z - 1.0f);
    p = (float3)(-p.x * z * geo[6], -p.y * z * geo[7], z);
  }
  bool inside = false;
  if (kind == REGION_BOX) {
    inside = p.x >= region[0] && p.y >= region[1] && p.z >= region[2] && p.x <= region[3] && p.y <= region[4] &&
             p.z <= region[5];
  } else if (kind == REGION_SPHERE) {
    const float3 d = p - (float3)(region[0], region[1], region[2]);
    inside = dot(d, d) <= region[3] * region[3];
  } else {
    const float t = dot(p - (float3)(region[0], region[1], region[2]), (float3)(region[3], region[4], region[5]));
    inside = t >= region[6] && t <= region[7];
  }
  out[i] = inside ? 1.0f : 0.0f;
}
