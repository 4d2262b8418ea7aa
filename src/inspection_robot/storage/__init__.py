"""The robot's stored files over the link: listing, metadata and chunked reads (file_control)."""
