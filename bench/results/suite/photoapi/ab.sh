#!/bin/bash
# alternating main (c3a8fbc, /tmp/photoapi/base) and branch (/work/wt/photoapi), 3 rounds
for r in 1 2 3; do
  cat /proc/loadavg >> /tmp/photoapi/ab_load.txt
  PYTHONPATH=/tmp/photoapi/base NUMBA_CACHE_DIR=/tmp/photoapi/base/.numba_cache ROS_DOMAIN_ID=92 nice -n 19 /work/main/.venv-bench/bin/python /tmp/photoapi/time_colour.py main /tmp/photoapi/t_main_$r.json 5
  cat /proc/loadavg >> /tmp/photoapi/ab_load.txt
  PYTHONPATH=/work/wt/photoapi NUMBA_CACHE_DIR=/work/wt/photoapi/.numba_cache ROS_DOMAIN_ID=92 nice -n 19 /work/main/.venv-bench/bin/python /tmp/photoapi/time_colour.py photoapi /tmp/photoapi/t_photoapi_$r.json 5
done
cat /proc/loadavg >> /tmp/photoapi/ab_load.txt
echo done
