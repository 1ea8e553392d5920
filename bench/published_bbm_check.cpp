// BBM's own evaluation of published MERL fits, to check bench/published.py against.
//
// Reads fits/<name>.fit lines of the BSDF benchmark BBM (github.com/bsdfbenchmark/bbm), imports each
// requested material's line with BBM's string importer (bbm::bsdf_import) and prints BBM's eval(in, out)
// at the direction pairs of a text file, one line per (material, pair):
//
//     <material> <pair index> <R> <G> <B>            (values printed with 21 significant digits)
//
// Usage:
//     published_bbm_check [--long-double] <file.fit> <directions.txt> <material>...
//
// directions.txt has one pair per line, "ix iy iz ox oy oz" (unit vectors, z the normal, both pointing away
// from the surface).  By default BBM's doubleRGB configuration (native backbone) is used; --long-double
// uses the same rgb configuration with long double values (for fits, like Ngan's Lafortune, whose
// terms over- or underflow in double).
//
// Build (BBM is header-only, C++20, g++ 12; only the native backbone and include/ are needed; the repository
// holds a few precomputed tables not needed here that a partial mirror may lack, hence the explicit list):
//
//     R=/work/.mirror/bsdfbenchmark+bbm/repo               # or any clone of BBM
//     git -C $R rev-parse HEAD                             # the commit checked: 9807fb38d7ab51802f3a0fe0f65cf763cb01a0f4
//     mkdir -p /tmp/bbm && git -C $R archive HEAD backbone/native \
//         $(git -C $R ls-tree --name-only HEAD include/ | grep -v precomputed) | tar -x -C /tmp/bbm
//     # the models BBM's cmake would list in its generated bbm_bsdfmodels.h (alphabetical, as cmake's glob:
//     # low.h and ngan.h use cooktorrance.h and he.h without including them)
//     # (git may report an invalid object for a precomputed table a partial mirror lacks: not needed here)
//     mkdir -p /tmp/bbm/gen && for h in ashikhminshirley bagher cooktorrance he lafortune lambertian low \
//         lowmicrofacet lowsmooth ngan phong ward wardduer; do echo "#include \"bsdfmodel/$h.h\""; \
//         done > /tmp/bbm/gen/bbm_bsdfmodels.h
//     g++-12 -std=c++20 -O2 -DBBM_STRING_BSDF_IMPORTER -DBBM_BACKBONE=native -DBBM_NAME=bbm -DBBM_VERSION=0 \
//         -I/tmp/bbm/gen -I/tmp/bbm/include -I/tmp/bbm/backbone/native/include \
//         bench/published_bbm_check.cpp -o /tmp/published_bbm_check
//
// Then, e.g.:  git -C $R show HEAD:fits/ngan_ward.fit > /tmp/ngan_ward.fit
//              /tmp/published_bbm_check /tmp/ngan_ward.fit dirs.txt blue-acrylic gold-metallic-paint3
//
// Not part of the package or its tests: tests/data/published_bbm/ holds a table this program printed.

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bbm.h"
#include "bbm/bsdf_import.h"

namespace bbm {
  //! BBM's rgb configuration of the native backbone with long double values (wavelengths as doubleRGB's).
  struct longdoubleRGB : public detail::rgbConfig<long double, "longdoubleRGB", longdoubleRGB> {};
}

namespace {

  //! material name -> the text after "name = " on its line of a .fit file ('#' lines skipped).
  std::map<std::string, std::string> read_fit(const char* path)
  {
    std::map<std::string, std::string> fits;
    std::ifstream file(path);
    std::string line;
    while(std::getline(file, line))
    {
      if(line.empty() || line[0] == '#') continue;
      auto eq = line.find(" = ");
      if(eq == std::string::npos) continue;
      fits[line.substr(0, eq)] = line.substr(eq + 3);
    }
    return fits;
  }

  std::vector<std::vector<double>> read_directions(const char* path)
  {
    std::vector<std::vector<double>> pairs;
    std::ifstream file(path);
    std::string line;
    while(std::getline(file, line))
    {
      std::istringstream in(line);
      std::vector<double> p(6);   // read as double: the same inputs as a float64 caller
      bool ok = true;
      for(auto& v : p) ok = ok && static_cast<bool>(in >> v);
      if(ok) pairs.push_back(p);
    }
    return pairs;
  }

  template<typename CONF>
  int run(const std::map<std::string, std::string>& fits, const std::vector<std::vector<double>>& pairs,
          const std::vector<std::string>& materials)
  {
    BBM_IMPORT_CONFIG(CONF);
    for(const auto& material : materials)
    {
      auto found = fits.find(material);
      if(found == fits.end()) { std::cerr << "no fit for " << material << std::endl; return 1; }
      auto bsdf = bbm::bsdf_import<CONF>(found->second);
      for(size_t i = 0; i < pairs.size(); ++i)
      {
        const auto& p = pairs[i];
        Vec3d in{Value(p[0]), Value(p[1]), Value(p[2])};
        Vec3d out{Value(p[3]), Value(p[4]), Value(p[5])};
        Spectrum f = bsdf.eval(in, out);
        std::printf("%s %zu %.21Lg %.21Lg %.21Lg\n", material.c_str(), i, (long double)f[0], (long double)f[1],
                    (long double)f[2]);
      }
    }
    return 0;
  }

}  // namespace

int main(int argc, char** argv)
{
  int arg = 1;
  bool long_double = (argc > 1 && std::strcmp(argv[1], "--long-double") == 0);
  if(long_double) ++arg;
  if(argc - arg < 3)
  {
    std::cerr << "usage: " << argv[0] << " [--long-double] <file.fit> <directions.txt> <material>..." << std::endl;
    return 2;
  }
  auto fits = read_fit(argv[arg]);
  auto pairs = read_directions(argv[arg + 1]);
  std::vector<std::string> materials(argv + arg + 2, argv + argc);
  if(long_double) return run<bbm::longdoubleRGB>(fits, pairs, materials);
  return run<bbm::doubleRGB>(fits, pairs, materials);
}
