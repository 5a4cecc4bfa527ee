// mp4 videos through ffmpeg (found on PATH): frames become a numbered PNG sequence, which ffmpeg encodes as
// H.264 in yuv420p (an odd width or height padded by one pixel, as yuv420p needs even sizes). The mp4 is
// written atomically: a failed or interrupted encode leaves no file under the real name.
#pragma once
#include <functional>
#include <ostream>
#include <string>

#include "lib/io/image.hpp"

namespace stylerf::io {

bool have_ffmpeg();

// Encodes the PNG sequence dir/pattern (e.g. "frame_%04d.png", numbered from 0) into `mp4` at `fps`
// frames a second. Throws Error when ffmpeg is not on PATH or fails (with the end of its output).
void encode_png_sequence(const std::string& dir, const std::string& pattern, const std::string& mp4, double fps);

// The rendering commands' video beside their frames: dir/pattern into dir/name. Without ffmpeg it returns
// false and tells `log` the command that would make it; throws when ffmpeg fails.
bool write_video(const std::string& dir, const std::string& pattern, const std::string& name, int fps,
                 std::ostream& log);

// `count` frames, frame(i) giving the i-th, into `mp4`; every frame must have the first one's size. The
// PNGs go to a temporary folder, removed afterwards, whatever happens. Throws Error, before any frame is
// asked for, on no frames, an fps that is not a positive number (at most 1000), a missing folder for
// `mp4` or no ffmpeg; an exception thrown by `frame` ends the call as it is.
void save_video(const std::string& mp4, int count, const std::function<Image(int index)>& frame, double fps);

}  // namespace stylerf::io
