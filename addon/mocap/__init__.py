"""Motion-capture files: Acclaim ASF/AMC import and export."""
