"""The gallery's image scraper: sphinx-gallery's matplotlib scraper with tight bounding boxes,
so that long titles and axis labels are not cut at the figure's edge."""

from __future__ import annotations


def tight(block, block_vars, gallery_conf, **kwargs):
    from sphinx_gallery.scrapers import matplotlib_scraper

    return matplotlib_scraper(block, block_vars, gallery_conf, bbox_inches="tight", **kwargs)
