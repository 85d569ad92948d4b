// Writes the demo scene's sky (tests/data/demo/sky.exr): a 128 x 64 lat-long OpenEXR in 32-bit
// float, image top = zenith (use with "up": "Z"). Blue at the zenith fading to a bright haze at the
// horizon, a brighter glow around the sun's direction, dark warm ground below. Deterministic, so
// the committed file can be regenerated: probebake_make_demo_sky OUT.exr. An optional size
// (probebake_make_demo_sky OUT.exr 2048 1024) writes the same sky larger, for measuring what a
// production-size map costs a bake (tests/bench/README.md).
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

int main(int argc, char** argv) {
  int w = 128, h = 64;
  if (argc == 4) w = std::atoi(argv[2]), h = std::atoi(argv[3]);
  if ((argc != 2 && argc != 4) || w < 2 || h < 2 || w > 16384 || h > 16384) {
    std::fprintf(stderr, "usage: %s OUT.exr [WIDTH HEIGHT]  (2 to 16384 each; default 128 64)\n",
                 argv[0]);
    return 2;
  }
  const double pi = std::acos(-1.0);
  // Toward the sun in map coordinates (+Y up): the demo's sun travels along
  // (0.3, -0.8, -0.5) in the world; "up": "Z" maps map (x, y, z) to world (x, -z, y), so the
  // direction toward it, world (-0.3, 0.8, 0.5), is map (-0.3, 0.5, -0.8).
  const double sx = -0.3, sy = 0.5, sz = -0.8, sn = std::sqrt(sx * sx + sy * sy + sz * sz);
  std::vector<float> r(size_t(w) * h), g(size_t(w) * h), b(size_t(w) * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // Imf::LatLongMap: latitude pi (1/2 - y/(h-1)), longitude 2 pi (1/2 - x/(w-1)).
      const double lat = pi * (0.5 - double(y) / (h - 1)),
                   lon = 2 * pi * (0.5 - double(x) / (w - 1));
      const double dx = std::sin(lon) * std::cos(lat), dy = std::sin(lat),
                   dz = std::cos(lon) * std::cos(lat);
      double cr, cg, cb;
      if (dy >= 0) {
        const double t = std::pow(1 - dy, 3);  // 0 at the zenith, 1 at the horizon
        cr = 0.25 + 0.75 * t, cg = 0.45 + 0.5 * t, cb = 1.1 + 0.0 * t;
        const double cosSun = (dx * sx + dy * sy + dz * sz) / sn;
        const double glow = 2.0 * std::exp(12 * (cosSun - 1));
        cr += glow, cg += 0.9 * glow, cb += 0.7 * glow;
      } else {
        cr = 0.12, cg = 0.10, cb = 0.08;
      }
      r[y * w + x] = float(cr), g[y * w + x] = float(cg), b[y * w + x] = float(cb);
    }
  }
  Imf::Header header(w, h);
  header.compression() = Imf::ZIP_COMPRESSION;
  for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
  Imf::OutputFile file(argv[1], header);
  Imf::FrameBuffer fb;
  fb.insert("R", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(r.data()), sizeof(float),
                            sizeof(float) * w));
  fb.insert("G", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(g.data()), sizeof(float),
                            sizeof(float) * w));
  fb.insert("B", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(b.data()), sizeof(float),
                            sizeof(float) * w));
  file.setFrameBuffer(fb);
  file.writePixels(h);
  return 0;
}
