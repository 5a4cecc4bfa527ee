// The background shell: what a ray sees after it leaves the scene's box, for captures whose photos show
// real surroundings (a room around an object on a table). The surroundings are a sphere of radius `radius`
// about the scene's centre, painted with a latitude-longitude map [H * W, C] (row 0 at +z, the capture's
// up); a ray's background is the map at the point where it leaves the sphere, bilinear in the map, and goes
// behind the ray as (1 - acc) * map(p). A sphere at a finite distance rather than at infinity keeps the
// parallax of a room seen by cameras circling inside it. lib/render/background_shell.hpp.

// The four bilinear texels (row-major index into the map) of each ray's exit point and their weights.
// Rows are clamped at the poles, columns wrap around the seam at phi = +-pi. An origin outside the sphere
// (no exit point ahead of it) reads the map by the direction alone, as a sphere at infinity would.
kernel void background_shell_taps(global const float* origins, global const float* dirs, int R, float radius,
                                  int H, int W, global int* idx, global float* w) {
  const int r = get_global_id(0);
  if (r >= R) return;
  const float3 o = vload3(r, origins);
  float3 d = vload3(r, dirs);
  const float len = length(d);
  d = len > 0.0f ? d / len : (float3)(0.0f, 0.0f, 1.0f);
  const float b = dot(o, d), c = dot(o, o) - radius * radius;
  float3 u = d;
  if (c < 0.0f) {
    const float t = -b + sqrt(fmax(b * b - c, 0.0f));
    u = (o + t * d) / radius;
  }
  const float pi = 3.14159265358979f;
  const float theta = acos(clamp(u.z / fmax(length(u), 1e-20f), -1.0f, 1.0f));
  const float phi = atan2(u.y, u.x);
  const float y = theta / pi * H - 0.5f, x = (phi + pi) / (2.0f * pi) * W - 0.5f;
  const float y0 = floor(y), x0 = floor(x);
  const float fy = y - y0, fx = x - x0;
  const int r0 = clamp((int)y0, 0, H - 1), r1 = clamp((int)y0 + 1, 0, H - 1);
  const int c0 = (((int)x0 % W) + W) % W, c1 = (c0 + 1) % W;
  idx[4 * r + 0] = r0 * W + c0;
  idx[4 * r + 1] = r0 * W + c1;
  idx[4 * r + 2] = r1 * W + c0;
  idx[4 * r + 3] = r1 * W + c1;
  w[4 * r + 0] = (1.0f - fy) * (1.0f - fx);
  w[4 * r + 1] = (1.0f - fy) * fx;
  w[4 * r + 2] = fy * (1.0f - fx);
  w[4 * r + 3] = fy * fx;
}

// out[r, c] += (1 - acc[r]) * sum_k w[r, k] map[idx[r, k], c]  (in place). The channel is the fastest
// index of the launch, so neighbouring work-items read neighbouring floats of a texel row.
kernel void background_shell_forward(global float* out, global const float* acc, global const float* map,
                                     global const int* idx, global const float* w, int R, int C) {
  const int c = get_global_id(0), r = get_global_id(1);
  if (r >= R || c >= C) return;
  float bg = 0.0f;
  for (int k = 0; k < 4; ++k) bg = fma(w[4 * r + k], map[(long)idx[4 * r + k] * C + c], bg);
  out[(long)r * C + c] = fma(1.0f - acc[r], bg, out[(long)r * C + c]);
}

// The gradient of that term w.r.t. acc: dacc[r] (+)= -<dout[r], bg_r>.
kernel void background_shell_dacc(global const float* dout, global const float* map, global const int* idx,
                                  global const float* w, int R, int C, global float* dacc, int accumulate) {
  const int r = get_global_id(0);
  if (r >= R) return;
  float s = 0.0f;
  for (int c = 0; c < C; ++c) {
    float bg = 0.0f;
    for (int k = 0; k < 4; ++k) bg = fma(w[4 * r + k], map[(long)idx[4 * r + k] * C + c], bg);
    s = fma(dout[(long)r * C + c], bg, s);
  }
  dacc[r] = (accumulate ? dacc[r] : 0.0f) - s;
}

// The gradient w.r.t. the map: dmap[texel, c] += sum over the taps on that texel of (1 - acc[ray]) w dout[ray, c].
// The taps come grouped by texel (a list the host sorts: texel[t], its entries offset[t] .. offset[t + 1]),
// so each texel is summed by one work-item and no two write the same place: no atomics, the same sum on
// every run.
kernel void background_shell_dmap(global const float* dout, global const float* acc, global const int* texel,
                                  global const int* offset, global const int* entry_ray,
                                  global const float* entry_w, int T, int C, global float* dmap) {
  const int c = get_global_id(0), t = get_global_id(1);
  if (t >= T || c >= C) return;
  float s = 0.0f;
  for (int e = offset[t]; e < offset[t + 1]; ++e) {
    const int r = entry_ray[e];
    s = fma((1.0f - acc[r]) * entry_w[e], dout[(long)r * C + c], s);
  }
  dmap[(long)texel[t] * C + c] += s;
}
