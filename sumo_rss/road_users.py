"""Classes of road users other than cars (rss.md §10): each has its own RSS parameter row, and the class is what
episodes.csv and violations.csv name it (class_a, class_b, vehicle_class)."""
BICYCLE_CLASS = "bicycle"  # a vehicle of SUMO vClass bicycle
PERSON_CLASS = "person"  # a SUMO person (a pedestrian)
