"""Small helpers of every stage; they import nothing of facepuppet but its errors."""
