# The GPU run of benchmarks/gpu.py, from the repository root on the GPU machine, with .gpu/ carried there (see
# benchmarks/gpu.py's docstring): [TIMEOUT=560 BUDGET=500] bash benchmarks/gpu_run.sh [gpu.py's options].
# Writes the rows, the tables and the log into $OUT.
set -o pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .gpu/whl/*.whl
export PYTHONPATH=/tmp/site:$PWD JAXSKID_CACHE_DIR=$PWD/.gpu/cache PYTHONUNBUFFERED=1
nvidia-smi -L
echo "C compiler: $(command -v cc gcc | head -1)"
ls -R .gpu/cache > $OUT/cache_before.txt
timeout ${TIMEOUT:-560} python3 benchmarks/gpu.py --budget ${BUDGET:-500} --out $OUT/gpu.jsonl --markdown $OUT/gpu.md "$@" 2>&1 | tee $OUT/log.txt
rc=$?
echo "new in the cache (derived or built here):"
ls -R .gpu/cache | diff $OUT/cache_before.txt - | grep '^>' | grep -v '^> .*\.\(bin\|cache\)$' | head -40
exit $rc
