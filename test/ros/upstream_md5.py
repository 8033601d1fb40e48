#!/usr/bin/env python3
"""Prints genmsg's md5sum of an upstream message type, computed from the upstream .msg files.

usage: upstream_md5.py UPSTREAM_DIR PACKAGE/TYPE
UPSTREAM_DIR holds <package>/msg/*.msg (../shared/upstream); ROS's own message packages are
read from /usr/share (Debian) or ROS_PACKAGE_PATH.
"""
import os
import sys

import genmsg.gentools
import genmsg.msg_loader


def search_path(upstream):
    paths = {}
    for pkg in os.listdir(upstream):
        if os.path.isdir(os.path.join(upstream, pkg, 'msg')):
            paths[pkg] = [os.path.join(upstream, pkg, 'msg')]
    roots = ['/usr/share'] + os.environ.get('ROS_PACKAGE_PATH', '').split(os.pathsep)
    for pkg in ('std_msgs', 'sensor_msgs', 'geometry_msgs'):
        for root in roots:
            d = os.path.join(root, pkg, 'msg')
            if root and os.path.isdir(d):
                paths.setdefault(pkg, []).append(d)
    return paths


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    upstream, msg_type = sys.argv[1], sys.argv[2]
    ctx = genmsg.msg_loader.MsgContext.create_default()
    paths = search_path(upstream)
    spec = genmsg.msg_loader.load_msg_by_type(ctx, msg_type, paths)
    genmsg.msg_loader.load_depends(ctx, spec, paths)
    print(genmsg.gentools.compute_md5(ctx, spec))


if __name__ == '__main__':
    main()
