#!/usr/bin/python3
"""Open3D's plane finding as its users write it: segment_plane, remove the inliers, again.

    open3d_planes.py CLOUD.ply LABELS.i32 DISTANCE_M MIN_POINTS MAX_PLANES TIME_LIMIT_S

Writes one int32 per point (its plane, or -1) and prints the seconds the loop took (loading
the file is not timed) and why it stopped. Debian's python3-open3d is 0.16, which has no
detect_planar_patches. Run with OMP_NUM_THREADS=1 for one core.
"""
import sys
import time

import numpy as np
import open3d as o3d


def main():
    cloud_path, labels_path = sys.argv[1], sys.argv[2]
    distance, min_points = float(sys.argv[3]), int(sys.argv[4])
    max_planes, time_limit = int(sys.argv[5]), float(sys.argv[6])
    o3d.utility.random.seed(7)
    cloud = o3d.io.read_point_cloud(cloud_path)
    labels = np.full(len(cloud.points), -1, dtype=np.int32)
    remaining = np.arange(len(cloud.points))
    rest = cloud
    planes = 0
    reason = "no plane left"
    start = time.perf_counter()
    while len(remaining) >= min_points and planes < max_planes:
        if time.perf_counter() - start > time_limit:
            reason = "stopped at the time limit"
            break
        _, inliers = rest.segment_plane(distance_threshold=distance, ransac_n=3,
                                        num_iterations=1000)
        if len(inliers) < min_points:
            break
        labels[remaining[inliers]] = planes
        planes += 1
        keep = np.ones(len(remaining), dtype=bool)
        keep[inliers] = False
        remaining = remaining[keep]
        rest = rest.select_by_index(inliers, invert=True)
    elapsed = time.perf_counter() - start
    labels.tofile(labels_path)
    print(f"{elapsed:.6f} {reason}")


if __name__ == "__main__":
    main()
