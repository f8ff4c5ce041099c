pstats.Stats(prof).sort_stats("tottime").print_stats(15)
