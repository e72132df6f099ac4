"""Motion-capture series and what is measured on them alone.

Rate, bridging of short gaps, the axis conventions of a file, which bodies a stream lacks, live frames, blocks
of frames, and the pose-noise model.
"""
