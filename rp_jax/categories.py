"""Semantic categories of interest points (Sec. IV-A-2, Fig. 9).

The paper analyses Extended CMU Seasons per category: building, vegetation, vehicle and
background (road, sky, ...). The synthetic world renders a per-pixel category map with these
ids, and real data may bring a segmentation folder using them (see ``SEGMENTATION_DIR``).
"""

BUILDING = 0
VEGETATION = 1
VEHICLE = 2
GROUND = 3  # road, sidewalk, grass, lane markings
SKY = 4
OTHER = 5  # street furniture, people, signs on poles, ...
UNKNOWN = -1  # in records: no category map for this image
UNLABELLED_PIXEL = 255  # in category maps: pixel without a category

NAMES = {
    BUILDING: "building",
    VEGETATION: "vegetation",
    VEHICLE: "vehicle",
    GROUND: "road/ground",
    SKY: "sky",
    OTHER: "other",
}

# The paper's Fig. 9 panels: building, vegetation, vehicle, and the rest as background.
FIGURE9_GROUPS = {
    "building": (BUILDING,),
    "vegetation": (VEGETATION,),
    "vehicle": (VEHICLE,),
    "background": (GROUND, SKY, OTHER),
}

# Category maps live beside a layout at <root>/SEGMENTATION_DIR/<image path relative to
# root, extension replaced by .png>, one uint8 id per pixel. The synthetic world writes them;
# for real data a user may provide them from any segmentation model.
SEGMENTATION_DIR = "segmentation"
