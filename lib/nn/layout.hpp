// Layout ops between per-ray rows and images: [R,C] with R = H*W row-major pixels <-> [1,C,H,W].
//
// Renderers produce one row of C values per ray (pixel); convolutions want channel planes. The two ops
// are transposes of each other, so each one's backward is the other (kernels/layout.cl, transpose2d).
#pragma once
#include "host/tensor.hpp"

namespace stylerf::nn {

using host::Tensor;

// rows [H*W, C], pixel p = y * W + x  ->  image [1, C, H, W].
Tensor rows_to_image(const Tensor& rows, int H, int W);
// d image [1,C,H,W] -> d rows [H*W, C] (the transpose of the forward: image_to_rows).
Tensor rows_to_image_backward(const Tensor& dimage);

// image [1, C, H, W]  ->  rows [H*W, C].
Tensor image_to_rows(const Tensor& image);
// d rows [H*W, C] -> d image [1,C,H,W] (the transpose of the forward: rows_to_image).
Tensor image_to_rows_backward(const Tensor& drows, int H, int W);

// Column blocks of row-major [R, C] matrices (kernels/layout.cl, copy_columns): per-ray values carried side by
// side through a renderer and taken apart after it.
// [R, A] and [R, B] -> [R, A + B]; its backward is take_columns of each part.
Tensor concat_columns(const Tensor& a, const Tensor& b);
// Columns [from, from + count) of x [R, C] -> [R, count].
Tensor take_columns(const Tensor& x, int from, int count);
// dy [R, count] -> dx [R, width]: dy at columns [from, from + count), zero elsewhere (take_columns' backward).
Tensor take_columns_backward(const Tensor& dy, int from, int width);

}  // namespace stylerf::nn
