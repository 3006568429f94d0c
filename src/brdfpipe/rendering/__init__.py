"""The rendering track: measured and manifold materials in Mitsuba 3 (Soler et al. 2018 §5.2).

A ``merl`` BSDF, a material-preview scene, the I¹⁻/I²⁺ bounce split,
blended images and their error maps (the noise-floor check included), and
the track's figures.  Imports :mod:`brdfpipe.data` and :mod:`brdfpipe.core`
(the manifold's path points reach it as MERL files, the acquisition's
direction sets as directions files, not as imports).

* :mod:`brdfpipe.rendering.render`  – the ``merl`` BSDF for Mitsuba 3;
* :mod:`brdfpipe.rendering.scene`  – the preview scene and its renders;
* :mod:`brdfpipe.rendering.bounce`  – a path tracer splitting I¹⁻ and I²⁺;
* :mod:`brdfpipe.rendering.capture` – closed-loop capture: the acquisition set-up's photographs and their observation tables;
* :mod:`brdfpipe.rendering.blend`   – blended images, error maps, the noise-floor check;
* :mod:`brdfpipe.rendering.figures` – pre-render grid, interpolation strip, error panel, floor-check plot.
"""
