# The environment guaca_py needs on the GPU machine (NVIDIA, headless, no network), sourced from the
# project root before the tests or a benchmark:
#     source benchmarks/gpu_env.sh && python3 benchmarks/paper_table.py --raster auto
# benchmarks/gpu_suite.sh sources it itself. It needs two git-ignored folders beside the checkout,
# carried to the machine with it:
#   .gl/   the GL loader packages the machine lacks (glvnd: EGL, GL, GLX, GLES, OpenGL, Vulkan), as
#          amd64 .debs, unpacked into / here. On a machine with network, from the project root:
#            mkdir -p .gl /tmp/amd64/partial; o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64
#            -oDir::State::Lists=/tmp/amd64'; apt-get $o update
#            (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
#   .whl/  CPython 3.12 manylinux wheels of the dependencies the machine's Python lacks, installed into
#          /tmp/site here: moderngl==5.13.0 glcontext==3.1.0 pyglm==2.8.3 trimesh==5.2.0 (and
#          flip-evaluator for FLIP in benchmarks/accuracy_scenes.py), fetched with
#            python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
#              --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
#              -d .whl moderngl==5.13.0 glcontext==3.1.0 pyglm==2.8.3 trimesh==5.2.0
# Then: PYTHONPATH holds /tmp/site and the checkout, Python output is unbuffered (a run cut at its
# time limit keeps what it printed), and EGL loads NVIDIA's vendor library.
if [ ! -d guaca_py ] || [ ! -d .gl ] || [ ! -d .whl ]; then
  echo "gpu_env.sh: source it from the project root, with .gl/ and .whl/ beside the checkout" >&2
  return 1 2>/dev/null || exit 1
fi
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
  || { return 1 2>/dev/null || exit 1; }
export PYTHONPATH=/tmp/site:$PWD${PYTHONPATH:+:$PYTHONPATH}
export PYTHONUNBUFFERED=1
if [ -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ]; then
  export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
fi
