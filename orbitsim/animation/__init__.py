"""``orbitsim animate``: movies of a run, drawn by the fixed-timestep render loop.

* :mod:`orbitsim.animation.loop`: the render loop itself, pure arithmetic (frame times, whole
  physics steps per frame, the interpolation weight alpha), testable without drawing anything;
* :mod:`orbitsim.animation.states`: where the physics states come from (the engine stepped as the
  frames need it, or a trace's recorded samples) and the interpolated state of every frame;
* :mod:`orbitsim.animation.draw`: one frame as an RGB image (matplotlib, Agg);
* :mod:`orbitsim.animation.encode`: MP4 through imageio-ffmpeg, GIF through Pillow, written to a
  temporary file and renamed, so the output path never holds half a movie.
"""
