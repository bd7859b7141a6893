"""Camera calibration: ``rmpl calibrate`` from checkerboard and ChArUco boards.

Modules, in the order the data flows: :mod:`.boards` (what was printed), :mod:`.frames`
(each camera's views from image folders or videos) with :mod:`.detect` (OpenCV's corner
detectors), :mod:`.intrinsics` (one camera's lens), :mod:`.extrinsics` (a spanning tree over
shared views), :mod:`.bundle` (one sparse bundle adjustment), :mod:`.world` (the world
frame), :mod:`.calibrate` (the chain), :mod:`.report` and :mod:`.output` (files);
:mod:`.check` checks a calibration against the people of a recording; :mod:`.render`
draws synthetic board images for tests and benchmarks.
"""
